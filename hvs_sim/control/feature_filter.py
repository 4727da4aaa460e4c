"""Temporal filter of the tracked corners before the servo law, predicted by the camera's own motion.

Each frame's tracked corners are measured independently (aligned to one template), so their noise is white:
~0.1 px per corner through the `phone_handheld` camera. On six DOF, L's weakest direction (tilt traded against
sideways shift) turns that noise into the camera's pose: 0.1 px there is ~30 mm and ~2° for a 15 cm target at
0.8 m. The robot knows how its camera moved between two frames (forward kinematics of the joint encoders, the
pose `ArmDriver` already reads), so the corners of the last estimate can be carried to the new frame: back-
projected at the depth the controller estimates from their scale, moved with the camera and projected again.
The estimate is then blended with the new measurement (an α-β-free exponential filter, α = `alpha`):

    ŝ_k = p(ŝ_{k−1}, ΔT_k) + α (s_k − p(ŝ_{k−1}, ΔT_k))

With exact prediction this averages ~(2 − α)/α frames of measurement noise (its std × √(α / (2 − α))) and
adds no lag to the motion the camera itself makes; a moving target or a depth error is corrected at rate α
per frame. A measurement farther than `gate_px` from the prediction (re-acquisition after occlusion, a target
that moved) restarts the filter there, and a lost or faulty frame clears it.
"""

from __future__ import annotations

import numpy as np

from hvs_sim.control.ibvs import IBVSController
from hvs_sim.render.camera import CameraPose
from hvs_sim.validate import check_number

FILTER_GATE_PX = 2.0  # a corner this far from its prediction restarts the filter at the measurement


class FeatureFilter:
    """Exponential filter of pinhole corner pixels (N, 2) with the camera's motion as prediction."""

    def __init__(self, K: np.ndarray, alpha: float, desired_px: np.ndarray, desired_depth: float,
                 gate_px: float = FILTER_GATE_PX):
        """desired_px and desired_depth: s* and Z*, from which the depth of the corners is estimated by their
        scale (Z = Z*·size(s*)/size(s)), as the IBVS controller does."""
        check_number("feature filter alpha", alpha, 0, 1, lo_open=True)
        check_number("feature filter gate (px)", gate_px, 0, lo_open=True)
        self.K, self.Kinv = np.asarray(K, float), np.linalg.inv(np.asarray(K, float))
        self.alpha, self.gate_px = float(alpha), float(gate_px)
        self.desired_px, self.desired_depth = np.asarray(desired_px, float).reshape(-1, 2), float(desired_depth)
        self._size_star = IBVSController.scale_of(self.desired_px)
        self.state: np.ndarray | None = None  # the filtered corners (pinhole px) of the last frame
        self.pose: CameraPose | None = None  # the camera's pose (forward kinematics) at the last frame
        self.restarts = 0  # measurements that restarted the filter (gate), for diagnostics

    def reset(self) -> None:
        self.state = self.pose = None

    def depth(self, px: np.ndarray) -> float:
        return self.desired_depth * self._size_star / max(IBVSController.scale_of(px), 1e-9)

    def predict(self, pose: CameraPose) -> np.ndarray:
        """The last estimate carried to the camera pose `pose` (a plane facing the camera at the scale's depth)."""
        z = self.depth(self.state)
        rays = np.c_[self.state, np.ones(len(self.state))] @ self.Kinv.T
        world = (z * rays) @ self.pose.R.T + self.pose.t
        cam = pose.to_camera(world)
        uv = cam @ self.K.T
        return uv[:, :2] / uv[:, 2:3]

    def update(self, measured_px: np.ndarray, pose: CameraPose, usable: bool = True) -> np.ndarray:
        """The filtered corners for this frame. `usable` False (lost, fault): the filter is cleared and the
        measurement passed through."""
        measured_px = np.asarray(measured_px, float)
        if not usable or not np.isfinite(measured_px).all():
            self.reset()
            return measured_px
        if self.state is None:
            out = measured_px
        else:
            pred = self.predict(pose)
            if not np.isfinite(pred).all() or np.linalg.norm(measured_px - pred, axis=1).max() > self.gate_px:
                out, self.restarts = measured_px, self.restarts + 1
            else:
                out = pred + self.alpha * (measured_px - pred)
        self.state, self.pose = out.copy(), pose
        return out

