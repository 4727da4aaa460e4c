"""Teach-by-showing: what the loop knows before it moves. The goal image (the arm at the reference pose, the people
left out), the template's box in it and the automatic near-goal growth, and the checks that the target is in view
from the start; shared by the loop and whoever asks what a run will be taught."""

from __future__ import annotations

import numpy as np

from hvs_sim.errors import ConfigError
from hvs_sim.render.camera import CameraPose
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.scene.world import Scene
from hvs_sim.servo.config import GOAL_ROI_INSET_PX, IN_VIEW_MARGIN_PX, MAX_TEMPLATE_GROWTH_PX
from hvs_sim.servo.parts import NEAR_GOAL_AREA, NEAR_GOAL_MIN_GROWTH_PX
from hvs_sim.tracking.frames import MIN_ROI, inset_roi, roi_corners


def corners_in_view(px: np.ndarray, camera, margin: float = 0.0) -> bool:
    """Whether all points (pixels) are finite and at least `margin` inside a camera's image."""
    hi = np.array([camera.width - 1, camera.height - 1]) - margin
    return bool(np.all(np.isfinite(px)) and np.all((px >= margin) & (px <= hi)))


def box_in_view(roi, camera) -> bool:
    """Whether a template box lies as far inside a camera's image as the switch to a grown template asks of its
    corners in the frame (TemplateSchedule.due: IN_VIEW_MARGIN_PX), so that a run given it can switch."""
    return corners_in_view(roi_corners(roi), camera, IN_VIEW_MARGIN_PX)


def near_goal_growth(outline, camera) -> tuple[int | None, str | None]:
    """The automatic near-goal template (LoopConfig.near_goal_inset_px = NEAR_GOAL_AUTO): the growth (px, negative
    as an inset) that takes the target's outline box in the goal image to NEAR_GOAL_AREA of the image, alike on every
    side, or less where the box would run out of the image (box_in_view). (None, why) where that is under
    NEAR_GOAL_MIN_GROWTH_PX: the one template is then nearly all there is to take."""
    x, y, w, h = (int(v) for v in outline)
    share = w * h / (camera.width * camera.height)
    # (w + 2g)(h + 2g) = NEAR_GOAL_AREA · W · H, the positive root; no more than a growth given may be
    g = int(np.floor((-(w + h) + np.sqrt((w + h) ** 2 + 4 * (NEAR_GOAL_AREA * camera.width * camera.height - w * h)))
                     / 4)) if share < NEAR_GOAL_AREA else 0
    g = min(g, MAX_TEMPLATE_GROWTH_PX)
    if g < NEAR_GOAL_MIN_GROWTH_PX:
        return None, (f"the target's box already holds {share:.0%} of the goal image (the near-goal template grows it "
                      f"to {NEAR_GOAL_AREA:.0%})")
    while g >= NEAR_GOAL_MIN_GROWTH_PX and not box_in_view(inset_roi((x, y, w, h), -g), camera):
        g -= 1
    if g < NEAR_GOAL_MIN_GROWTH_PX:
        return None, (f"the target's box lies within {NEAR_GOAL_MIN_GROWTH_PX} px of the goal image's edge: no room "
                      "to grow the near-goal template")
    return -g, None


def check_start_in_view(scene: Scene, renderer: Renderer) -> None:
    """ConfigError unless all four target corners are inside the image from the scenario's start pose."""
    start_pos, start_R = scene.start_pose()
    px = renderer.project(CameraPose(start_R, start_pos), scene.target_corners_world())
    cam = scene.scenario.camera
    if not corners_in_view(px, cam, IN_VIEW_MARGIN_PX):
        raise ConfigError(f"from the start offset {scene.scenario.start_offset_text} the target is not fully in view "
                          f"(its corners at {np.round(px, 1).tolist()} px in a {cam.width}×{cam.height} image): "
                          "give a smaller offset")


def check_start_pose(scenario: Scenario) -> None:
    """ConfigError when the arm cannot reach the scenario's start pose or the target is not fully in view
    from it (builds the scene, renders nothing)."""
    scene = Scene(scenario)
    check_start_in_view(scene, Renderer(scene))


def default_inset(roi, template_from: str, oracle: bool) -> int:
    """LoopConfig.roi_inset_px=None: GOAL_ROI_INSET_PX for a goal template, less where the box would fall under MIN_ROI
    (a target small in the image); 0 for a start template, whose box is thin at large rolls, and for the oracle."""
    if template_from == "start" or oracle:
        return 0
    return int(min(GOAL_ROI_INSET_PX, max(0, (min(roi[2], roi[3]) - MIN_ROI) // 2)))


def goal_image(scene: Scene, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(frame, target corners) of the goal image: the camera at the reference pose at time 0, the people left out (a
    user teaches the goal in a clear scene), through the run's camera model: the mean of `frames` frames of it."""
    teacher = Renderer(scene, people=False)  # its own sensor state: the episode's frames are unchanged
    with scene.posed(scene.reference_configuration()):
        return teacher.still_average(frames), teacher.ground_truth(occlusion=False).corners
