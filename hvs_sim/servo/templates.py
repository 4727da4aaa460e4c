"""The template schedule: the box the features start on (in the first frame, or in the goal image) and the grown
near-goal box the loop switches to once the features are near s* (LoopConfig.near_goal_*). Apart from the loop so that
the loop asks three questions (`start` at step 0, `due` after each step's control, `switch` when due) and never
re-derives the template rules. hvs_sim.servo.loop imports this module, never the reverse."""

from __future__ import annotations

import numpy as np

from hvs_sim import plugins
from hvs_sim.errors import InputError, StateError
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.world import Scene
from hvs_sim.servo.config import IN_VIEW_MARGIN_PX, LoopConfig
from hvs_sim.servo.parts import NEAR_GOAL_AUTO, Capture, Episode, Measured, ResolvedLoop, Template
from hvs_sim.servo.teach import box_in_view, corners_in_view, default_inset, goal_image, near_goal_growth
from hvs_sim.tracking.frames import inset_roi, roi_corners, roi_from_corners
from hvs_sim.tracking.warp import apply as apply_warp
from hvs_sim.tracking.warp import perspective_transform


class TemplateSchedule:
    """Where the features' template comes from, and when and how the grown near-goal one takes over."""

    def __init__(self, scene: Scene, renderer: Renderer, config: LoopConfig, resolved: ResolvedLoop,
                 tracker_name: str, tracker, near_goal_tracker, flag_desired: np.ndarray):
        """tracker: the loop's; near_goal_tracker: the one for the grown template where it is another (None: the
        loop's own goes on)."""
        self.scene, self.renderer, self.config, self.resolved = scene, renderer, config, resolved
        self.tracker_name, self.tracker, self.flag_desired = tracker_name, tracker, flag_desired
        self.oracle, self.near_goal_tracker = tracker_name == plugins.GROUND_TRUTH, near_goal_tracker
        self.near_goal_growth: int | None = None  # the near-goal template's growth as step 0 decided it
        self.near_goal_off = resolved.near_goal_off  # why there is none, where NEAR_GOAL_AUTO did not apply

    def goal_image(self) -> tuple[np.ndarray, np.ndarray]:
        """The goal image and the target's corners in it (servo/teach.py), with this run's goal frames."""
        if self.resolved.goal_frames is None:
            raise StateError("this run's template is taken from its first frame: it has no goal image")
        return goal_image(self.scene, self.resolved.goal_frames)

    def default_inset(self, roi) -> int:
        return default_inset(roi, self.resolved.template_from, self.oracle)

    def start(self, cap: Capture) -> tuple[np.ndarray | None, np.ndarray | None, Template, np.ndarray, Template | None]:
        """Step 0's templates: (the template's image, the goal image or None, the template, the target's corners in
        its image, the grown near-goal template or None). InputError when a grown box runs off the goal image."""
        res = self.resolved
        # the template's image and the target's corners in it: this first frame, or the goal image
        template_frame: np.ndarray | None  # None: the oracle's run from the first frame, which renders none
        template_frame, flag0 = (cap.obs.frame, cap.truth.corners) if res.template_from == "start" \
            else self.goal_image()
        goal = None if res.template_from == "start" else template_frame
        outline = roi_from_corners(flag0)
        inset = self.default_inset(outline) if res.roi_inset_px is None else res.roi_inset_px
        template = self._template(flag0, self.box(outline, inset, "roi_inset_px"), inset)
        near_goal, growth = None, None
        if res.near_goal == NEAR_GOAL_AUTO:
            growth, self.near_goal_off = near_goal_growth(outline, self.scene.scenario.camera)
        elif res.near_goal is not None:
            growth = int(res.near_goal)
        self.near_goal_growth = growth
        if growth is not None:  # the grown box checked now: a run that cannot switch says so
            near_goal = self._template(flag0, self.box(outline, growth, "near_goal_inset_px"), growth)
        return template_frame, goal, template, flag0, near_goal

    def _template(self, flag0: np.ndarray, roi, inset: int) -> Template:
        """A box in the template's image, its corners, and where they are at the reference pose (s*)."""
        corners = roi_corners(roi)
        return Template(roi, corners, inset, self.renderer.transfer(flag0, self.flag_desired, corners))

    def box(self, outline, inset: int, option: str) -> tuple[int, int, int, int]:
        """The template's box: the target's outline box inset (grown, when negative); InputError when a grown box runs
        off the goal image."""
        roi = inset_roi(outline, inset)
        cam = self.scene.scenario.camera  # the goal image's size (a run may render no frames)
        if inset < 0 and not box_in_view(roi, cam):
            raise InputError(f"the template grown {-inset} px beyond the target's outline, {roi[2]}×{roi[3]} px at "
                             f"({roi[0]}, {roi[1]}), runs off the {cam.width}×{cam.height} goal image: grow it less (a "
                             f"{option} nearer 0)")
        return roi

    def due(self, ep: Episode, seen: Measured) -> None:
        """After a step's control: when the features (as control used them) are within near_goal_px of s* and the
        grown box, carried by their homography, is in view, the switch to the grown template is due at the next
        step (ep.grow_from: that homography, the tracker's seed)."""
        if (ep.near_goal is None or ep.grown_at is not None or seen.fault is not None or seen.mode != "align"
                or ep.gate.closed_because is not None):
            return
        if float(np.linalg.norm(seen.features - ep.desired, axis=1).mean()) > self.config.near_goal_within_px:
            return
        A = perspective_transform(ep.roi0, seen.features)  # frame from goal image
        grown = apply_warp(A, ep.near_goal.corners)
        if corners_in_view(grown, self.scene.scenario.camera, IN_VIEW_MARGIN_PX):
            ep.grow_from = A

    def switch(self, ep: Episode, tracker, step: int):
        """The tracker (or the near-goal one, near_goal_scale) initialised on the grown template and seeded where the
        small one's corners put it, the episode's template fields moved to the grown box; returns the tracker that
        goes on. The loop then starts s*'s users again (the law, the feature filter, the gate)."""
        near, A = ep.near_goal, ep.grow_from
        if near is None or A is None:
            raise StateError(f"no switch to a near-goal template is due at step {step}")
        tracker = self.near_goal_tracker or tracker
        try:
            tracker.init(ep.template_frame, near.roi)
            tracker.seed(A)
        except Exception as exc:  # any cause: the tracker has no template left to servo on
            raise StateError(f"tracker {self.tracker_name!r} could not switch to the near-goal template (ROI "
                             f"{near.roi}) at step {step}: {exc}") from exc
        ep.roi, ep.roi0, ep.inset, ep.desired = near.roi, near.corners, near.inset, near.desired
        ep.grown_at, ep.grow_from = step, None
        return tracker

    def plan(self, switched_at: int | None) -> dict | None:
        """run.json's near_goal: the grown template as this run had it (None: LoopConfig.near_goal_inset_px=None)."""
        c = self.config
        if c.near_goal_inset_px is None:
            return None
        on = self.near_goal_off is None
        return {"inset_px": self.near_goal_growth, "auto": c.near_goal_inset_px == NEAR_GOAL_AUTO,
                "within_px": c.near_goal_within_px if on else None,
                "scale": (self.resolved.near_goal_scale or self.tracker.working_scale) if on else None,
                "off": self.near_goal_off, "switched_at_step": switched_at,
                "note": "the step from which the grown template's corners were the features (null: never switched); "
                        "off: why the run kept one template"}
