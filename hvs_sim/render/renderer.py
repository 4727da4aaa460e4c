"""RGB and segmentation renders of the eye camera, and exact per-frame ground truth."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control.mujoco.wrapper import core as mj_core

from hvs_sim.render.camera import CameraPose, intrinsics, project
from hvs_sim.scene.parts import OCCLUDER_GROUP, FlagWall
from hvs_sim.scene.world import Scene


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

    @staticmethod
    def intrinsics_of(scenario) -> np.ndarray:
        cam = scenario.camera
        return intrinsics(cam.width, cam.height, cam.fovy)

    def rgb(self) -> np.ndarray:
        """H×W×3 uint8 RGB frame."""
        return self.scene.physics.render(self.height, self.width, camera_id=self._camera_id,
                                        scene_option=self._show_people)

    def _target_mask(self, hide_people: bool) -> np.ndarray:
        seg = self.scene.physics.render(self.height, self.width, camera_id=self._camera_id, segmentation=True,
                                        scene_option=self._hide_people if hide_people else self._show_people)
        return (seg[..., 0] == self._target_id) & (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM))

    def target_mask(self) -> np.ndarray:
        """Boolean mask of the target's pixels that are not hidden by anything."""
        return self._target_mask(hide_people=False)

    def camera_pose(self) -> CameraPose:
        b = self.scene.physics.bind(self.scene.camera)
        return CameraPose.from_mujoco(b.xpos, b.xmat)

    def target_corners_world(self) -> np.ndarray:
        g = self.scene.physics.bind(self.scene.wall.target)
        R = g.xmat.reshape(3, 3)
        return g.xpos + FlagWall.corner_offsets() @ R.T

    def target_center_world(self) -> np.ndarray:
        g = self.scene.physics.bind(self.scene.wall.target)
        return g.xpos + g.xmat.reshape(3, 3) @ FlagWall.corner_offsets()[:, :].mean(axis=0)

    def ground_truth(self, occlusion: bool = True) -> GroundTruth:
        """Projected target geometry and (if asked) the occlusion from two segmentation renders."""
        pose = self.camera_pose()
        corners = project(self.K, pose, self.target_corners_world())
        centre_w = self.target_center_world()
        center = project(self.K, pose, centre_w)[0]
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
