"""RGB and segmentation renders of the eye camera, and exact per-frame ground truth.

RGB frames go through the scenario's camera model (`hvs_sim.camera_model`): motion blur from
sub-frame renders over the exposure, lens distortion, auto-exposure, sensor noise, JPEG. Ground
truth comes from geometry only; with lens distortion it is projected through the same model.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import mujoco
import numpy as np
from dm_control.mujoco.wrapper import core as mj_core

from hvs_sim.camera_model import SensorState, decode, distort_points, distortion_maps, light_scale
from hvs_sim.gl import check_not_forked_after_rendering, note_rendering
from hvs_sim.render.camera import CameraPose, intrinsics, project, transfer_points
from hvs_sim.scene.parts import OCCLUDER_GROUP
from hvs_sim.scene.world import Scene

PERSON_PROBE_HEIGHTS = (0.5, 1.2, 1.7)  # m above the feet: points whose image motion sets the blur sampling
BLUR_PROBE_MARGIN = 0.25  # ... counted while within this fraction of the image size outside the frame


@dataclass(frozen=True)
class GroundTruth:
    """What is true at one frame. Pixel values use the pixel-centre convention."""

    frame: int
    time: float
    center: np.ndarray  # (2,) projected centre of the target flag
    corners: np.ndarray  # (4, 2) TL, TR, BR, BL
    occlusion: float  # share of the target's pixels hidden by people, from segmentation renders
    visible_px: int
    full_px: int
    camera: CameraPose
    target_depth: float  # z of the target centre in the camera frame (m)
    joint_positions: np.ndarray

    def as_row(self) -> dict:
        return {
            "frame": self.frame, "time": round(self.time, 6), "cx": self.center[0], "cy": self.center[1],
            **{f"{a}{i}": self.corners[i, j] for i in range(4) for j, a in enumerate("xy")},
            "occlusion": self.occlusion, "visible_px": self.visible_px, "full_px": self.full_px,
            "depth": self.target_depth,
        }


class Renderer:
    """Renders the scene's eye camera. Segmentation renders give the exact occlusion fraction."""

    def __init__(self, scene: Scene):
        check_not_forked_after_rendering()
        self.scene = scene
        cam = scene.scenario.camera
        self.width, self.height = cam.width, cam.height
        self.K = self.intrinsics_of(scene.scenario)
        self._camera_id = scene.physics.bind(scene.camera).element_id
        self._target_id = scene.physics.bind(scene.wall.target).element_id
        self._show_people = mj_core.MjvOption()
        self._show_people.geomgroup[OCCLUDER_GROUP] = 1
        self._hide_people = mj_core.MjvOption()
        self._hide_people.geomgroup[OCCLUDER_GROUP] = 0
        self.sensor = cam.sensor
        self._state = None if self.sensor.is_ideal else SensorState(self.sensor, scene.scenario.seed, (self.height, self.width))
        # the lights as modelled; flicker and dimming scale them during a capture and put them back after
        self._maps = distortion_maps(self.K, self.sensor.distortion, self.width, self.height) if self.sensor.distortion else None
        m = scene.physics.model
        self._light0 = (m.light_diffuse.copy(), m.light_ambient.copy(), m.vis.headlight.diffuse.copy(),
                        m.vis.headlight.ambient.copy())
        self._last: tuple[tuple[int, int], np.ndarray] | None = None  # ((scene resets, frame), frame): one capture a frame
        self.blur_samples = 1  # sub-frame renders used for the last frame (diagnostics)

    @staticmethod
    def intrinsics_of(scenario) -> np.ndarray:
        cam = scenario.camera
        return intrinsics(cam.width, cam.height, cam.fovy)

    def _render(self) -> np.ndarray:
        note_rendering()
        return self.scene.physics.render(self.height, self.width, camera_id=self._camera_id,
                                         scene_option=self._show_people)

    def rgb(self) -> np.ndarray:
        """H×W×3 uint8 RGB frame as the camera delivers it (the raw render for the `ideal` model)."""
        if self.sensor.is_ideal:
            return self._render()
        scene = self.scene
        key = (scene.resets, scene.frame_index)
        if self._last is not None and self._last[0] == key:
            return self._last[1].copy()  # auto-exposure and noise advance once per frame
        if self._last is not None and self._last[0][0] != key[0]:
            self._state = SensorState(self.sensor, scene.scenario.seed, (self.height, self.width))  # a new episode
        offsets = self.sensor.exposure_offsets(self.sensor.samples_for_motion(self._exposure_motion_px()))
        self.blur_samples = len(offsets)
        linear = np.zeros((self.height, self.width, 3), np.float32)
        try:
            for dt in offsets:
                with scene.rewound(float(dt)):
                    self._set_lights(scene.time - float(dt))
                    linear += decode(self._render())
        finally:
            self._set_lights(None)
        linear /= np.float32(len(offsets))
        if self._maps is not None:
            linear = cv2.remap(linear, *self._maps, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        frame = self._state.capture(linear, scene.frame_index, scene.time, 1.0 / scene.scenario.fps)
        self._last = (key, frame)
        return frame.copy()

    def _set_lights(self, t: float | None) -> None:
        """Scale the scene's lights for the camera model's flicker / dimming at time t; None puts them back."""
        if not self.sensor.lights_change:
            return
        k = 1.0 if t is None else light_scale(self.sensor, self.scene.scenario.seed, t)
        m = self.scene.physics.model
        m.light_diffuse[:] = self._light0[0] * k
        m.light_ambient[:] = self._light0[1] * k
        m.vis.headlight.diffuse[:] = self._light0[2] * k
        m.vis.headlight.ambient[:] = self._light0[3] * k

    def _exposure_motion_px(self) -> float:
        """Largest image motion during the exposure of the target centre and the people (for blur sampling)."""
        if self.sensor.exposure_ms <= 0 or self.sensor.blur_max_samples == 1:
            return 0.0
        now = self._moving_points_px()
        with self.scene.rewound(self.sensor.exposure_ms * 1e-3):
            then = self._moving_points_px()
        d = np.linalg.norm(now - then, axis=1)
        margin = BLUR_PROBE_MARGIN * np.array([self.width, self.height])
        inside = np.all((now > -margin) & (now < [self.width, self.height] + margin), axis=1)
        d = d[inside & np.isfinite(d)]
        return float(d.max()) if d.size else 0.0

    def _moving_points_px(self) -> np.ndarray:
        pts = [self.target_center_world()]
        for pos, R in self.scene.people_poses():
            pts += [pos + R @ np.array([0.0, 0.0, z]) for z in PERSON_PROBE_HEIGHTS]
        return project(self.K, self.camera_pose(), np.array(pts))

    def transfer(self, corners_from: np.ndarray, corners_to: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """`transfer_points` through this camera's lens (exact with distortion too)."""
        return transfer_points(corners_from, corners_to, pts, self.K, self.sensor.distortion)

    def project(self, pose: CameraPose, points_world: np.ndarray) -> np.ndarray:
        """Where world points appear in this camera's frames: pinhole, then the lens distortion if any."""
        uv = project(self.K, pose, points_world)
        return distort_points(self.K, self.sensor.distortion, uv) if self.sensor.distortion else uv

    def _target_mask(self, hide_people: bool) -> np.ndarray:
        note_rendering()
        seg = self.scene.physics.render(self.height, self.width, camera_id=self._camera_id, segmentation=True,
                                        scene_option=self._hide_people if hide_people else self._show_people)
        return (seg[..., 0] == self._target_id) & (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM))

    def target_mask_distorted(self) -> np.ndarray:
        """The target's unhidden pixels in the camera's (distorted) image; equals `target_mask` without distortion."""
        mask = self.target_mask()
        if self._maps is None:
            return mask
        return cv2.remap(mask.astype(np.uint8), *self._maps, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT) > 0

    def target_mask(self) -> np.ndarray:
        """Boolean mask of the target's pixels that are not hidden by anything."""
        return self._target_mask(hide_people=False)

    def camera_pose(self) -> CameraPose:
        b = self.scene.physics.bind(self.scene.camera)
        return CameraPose.from_mujoco(b.xpos, b.xmat)

    def target_corners_world(self) -> np.ndarray:
        g = self.scene.physics.bind(self.scene.wall.target)
        R = g.xmat.reshape(3, 3)
        return g.xpos + self.scene.wall.corner_offsets() @ R.T

    def target_center_world(self) -> np.ndarray:
        g = self.scene.physics.bind(self.scene.wall.target)
        return g.xpos + g.xmat.reshape(3, 3) @ self.scene.wall.corner_offsets()[:, :].mean(axis=0)

    def ground_truth(self, occlusion: bool = True) -> GroundTruth:
        """Projected target geometry and (if asked) the occlusion from two segmentation renders."""
        pose = self.camera_pose()
        corners = self.project(pose, self.target_corners_world())
        centre_w = self.target_center_world()
        center = self.project(pose, centre_w)[0]
        visible = full = 0
        occ = float("nan")
        if occlusion:
            visible = int(self.target_mask().sum())
            full = visible if not self.scene.people else int(self._target_mask(hide_people=True).sum())
            occ = 1.0 - visible / full if full > 0 else 1.0
        return GroundTruth(
            frame=self.scene.frame_index, time=self.scene.time, center=center, corners=corners,
            occlusion=occ, visible_px=visible, full_px=full, camera=pose,
            target_depth=float(pose.to_camera(centre_w)[0, 2]), joint_positions=self.scene.joint_positions)
