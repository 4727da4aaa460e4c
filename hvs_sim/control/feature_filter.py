"""Temporal filter of the tracked corners before the servo law, predicted by the camera's own motion.

Each frame's tracked corners are measured on their own (aligned to one template), so their noise is white:
~0.1 px per corner through the `phone_handheld` camera. On six DOF, L's weakest direction (tilt traded against
sideways shift) turns 0.1 px there into ~18 mm and ~1.3° of camera pose for a 15 cm target at 0.8 m. The robot
knows how its camera moved between two frames (the joints' forward kinematics, the pose `ArmDriver` reads), so
the last estimate can be carried to the new frame by the homography the target's plane induces between the two
views (the plane from the last estimate and the planar model the controller knows, s* at Z*, by IPPE). The
estimate is then blended with the new measurement by a first-order filter:

    ŝ_k = p(ŝ_{k−1}, ΔT_k) + α (s_k − p(ŝ_{k−1}, ΔT_k))

For a still target the prediction is exact, so the filter adds no lag to what the camera does and averages
~(2 − α)/α frames of measurement noise (its std × √(α / (2 − α))). What the camera's motion does not explain, a
moving target, is followed at rate α per frame, and a measurement farther than `gate_px` from the prediction
(re-acquisition after occlusion, a target that moved fast) restarts the filter there; a lost or faulty frame
clears it.
"""

from __future__ import annotations

import numpy as np

from hvs_sim.control.pose import target_model, target_pose
from hvs_sim.render.camera import CameraPose
from hvs_sim.validate import check_number

# LoopConfig.feature_filter's default for tracked corners on six DOF (tuned on servo episodes 300-305: 0.1 and 0.2
# alike, 0.05 no better; README)
FEATURE_FILTER_ALPHA = 0.1
FILTER_GATE_PX = 2.0  # a corner this far from its prediction restarts the filter at the measurement


class FeatureFilter:
    """First-order filter of pinhole corner pixels (4, 2) with the camera's motion as prediction."""

    def __init__(self, K: np.ndarray, alpha: float, desired_px: np.ndarray, desired_depth: float,
                 gate_px: float = FILTER_GATE_PX):
        """desired_px and desired_depth: s* and Z*, the planar target model the controller is given."""
        check_number("feature filter alpha", alpha, 0, 1, lo_open=True)
        check_number("feature filter gate (px)", gate_px, 0, lo_open=True)
        self.K = np.asarray(K, float)
        self.K_inv = np.linalg.inv(self.K)
        self.alpha, self.gate_px = float(alpha), float(gate_px)
        self.model = target_model(desired_px, desired_depth, self.K)
        self.state: np.ndarray | None = None  # the filtered corners (pinhole px) of the last frame
        self.pose: CameraPose | None = None  # the camera's pose (forward kinematics) at the last frame
        self.restarted = False  # whether the last update restarted the filter at the measurement (gate)

    def reset(self) -> None:
        self.state = self.pose = None

    def predict(self, pose: CameraPose) -> np.ndarray | None:
        """The last estimate carried to the camera pose `pose` by the homography the target's plane induces between
        the two views, H = K (R + t nᵀ / d) K⁻¹: (R, t) the camera's motion, n, d the plane in the last camera frame
        (from the target's pose, IPPE on the last estimate). H is the identity when the camera has not moved, so
        the estimate itself, not a pose fitted to it, is carried. None when the plane cannot be had."""
        found = target_pose(self.model, self.K, self.state)
        if found is None:
            return None
        R_t, t_t = found
        n = R_t[:, 2]  # the model's plane is z = Z* in its own frame
        d = float(n @ (R_t @ self.model[0] + t_t))
        R = pose.R.T @ self.pose.R  # last camera frame → this one
        t = pose.R.T @ (self.pose.t - pose.t)
        H = self.K @ (R + np.outer(t, n) / d) @ self.K_inv
        uv = np.c_[self.state, np.ones(len(self.state))] @ H.T
        return uv[:, :2] / uv[:, 2:3] if d > 0 and np.all(uv[:, 2] > 0) else None

    def update(self, measured_px: np.ndarray, pose: CameraPose, usable: bool = True) -> np.ndarray:
        """The filtered corners for this frame. `usable` False (lost, fault): the filter is cleared and the
        measurement passed through."""
        measured_px = np.asarray(measured_px, float)
        self.restarted = False
        if not usable or not np.isfinite(measured_px).all():
            self.reset()
            return measured_px
        out = measured_px
        if self.state is not None:
            pred = self.predict(pose)
            if pred is None or np.linalg.norm(measured_px - pred, axis=1).max() > self.gate_px:
                self.restarted = True
            else:
                out = pred + self.alpha * (measured_px - pred)
        self.state, self.pose = out.copy(), pose
        return out
