"""Position-based visual servoing beside IBVS: the target's pose from the tracked corners, then the
classic PBVS law on the camera's displacement (Chaumette & Hutchinson 2006, e = (c*t_c, θu)).

The target model is what the controller is given for IBVS too: the desired corners s* seen at the
desired depth Z* with the target plane facing the camera, i.e. P_i = Z* K⁻¹ (u*_i, v*_i, 1). The
current pose cTo of that model is the least-squares fit to the tracked corners (IPPE, then refined over the pose's
six parameters: target_pose), and with the model in the desired camera frame c*To = I, so c*Tc = (cTo)⁻¹ and

    v = −λ c*R_cᵀ c*t_c = λ t,    ω = −λ θu(c*R_c) = λ θu(R),    where cTo = (R, t).

The camera then moves on a straight line to the goal (the target may leave the view on the way,
which the servo benchmark counts). The gain schedule, the predict-mode gain, the lost rule and the
twist bounds are IBVS's (IBVSConfig), so the two laws differ only in the error they regulate.

The pose matters: IPPE alone fits the plane's homography to the four corners exactly, and at 0.07 px of corner noise
its pose swings by ±2.2° and ±31 mm from frame to frame along the direction four corners of a small target barely see
(a sideways shift traded against a tilt); the arm turned those swings into image motion, and no tracked-corner episode
of the servo benchmark held the goal. The least-squares pose swings by ±0.6° and ±9 mm, as the IBVS law's L⁺ sees the
same noise. With IBVSConfig.damping > 0 (the loop's default for tracked corners on six DOF, as for IBVS) the pose
error is also weighted by (LᵀL + μ²I)⁻¹LᵀL, the damped IBVS law's weighting (the two agree to first order near the
goal).
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.control.features import PointFeatures, interaction_matrix
from hvs_sim.control.laws.ibvs import PREDICT_DOFS, SIMILARITY_DOFS, ControlOutput, IBVSConfig, bound_twist, image_terms
from hvs_sim.control.pose import target_model, target_pose
from hvs_sim.control.protocol import DOF_NAMES, ControlInput
from hvs_sim.errors import InputError


class PBVSController:
    """PBVS to the pose that shows the desired corners s* (pixels) at depth Z*, given intrinsics K."""

    def __init__(self, K: np.ndarray, desired_px: np.ndarray, desired_depth: float, config: IBVSConfig | None = None,
                 dofs: tuple[str, ...] = SIMILARITY_DOFS):
        config = config or IBVSConfig()
        # s* checked and normalised as IBVS's: its image error, gain schedule and L are reported beside the pose's
        self.points = PointFeatures(K, desired_px, desired_depth)
        self.config, self.K, self.desired_px = config, self.points.K, self.points.desired_px
        self.dofs = tuple(config.dofs or dofs)
        self.cols = [DOF_NAMES.index(d) for d in self.dofs]
        self.predict_cols = [c for c in self.cols if DOF_NAMES[c] in PREDICT_DOFS]
        if len(self.points.s_star) < 4:
            raise InputError(f"PBVS needs at least 4 coplanar corners for the target's pose, got {len(self.points.s_star)}")
        self.model = target_model(self.desired_px, desired_depth, self.K)

    def pose(self, features_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(R, t) of the target model in the current camera frame from the corners (pixels)."""
        pose = target_pose(self.model, self.K, features_px, refine=True)
        if pose is None:
            raise InputError("PBVS: the target's pose could not be estimated from these corners")
        return pose

    def shrunk(self, error: np.ndarray, features_px: np.ndarray) -> np.ndarray:
        """The pose error with its directions weighted by how well the corners see them: (LᵀL + μ²I)⁻¹ LᵀL e, L the
        interaction matrix of the corners (at the current and desired corners, as IBVS's), μ = damping · σ_max(L).
        The pose from four corners of a small target is noisy along L's weak direction (a sideways shift traded
        against a tilt); this is the least-squares pose error regularised toward zero motion there."""
        pts = self.points
        s = pts.error(features_px)[0]
        Z = np.full(len(s), pts.desired_depth)
        L = 0.5 * (interaction_matrix(s, Z) + interaction_matrix(pts.s_star, Z))
        A = L.T @ L
        mu2 = (self.config.damping * np.sqrt(np.linalg.eigvalsh(A)[-1])) ** 2
        return np.linalg.solve(A + mu2 * np.eye(6), A @ error)

    def compute(self, features_px, depths: np.ndarray | None = None, mode: str = "align") -> ControlOutput:
        """Twist for the current corners: a ControlInput (control/protocol.py) or pixels; `depths` is not used (the
        pose gives them)."""
        if isinstance(features_px, ControlInput):
            features_px, depths, mode = features_px.features_px, features_px.depths, features_px.mode
        img = image_terms(self.points, self.config, features_px, None if self.config.depth != "true" else depths, mode,
                          self.cols, self.predict_cols)
        twist = np.zeros(6)
        if mode != "lost":
            R, t = self.pose(features_px)
            theta_u = cv2.Rodrigues(R)[0].reshape(3)
            error = np.concatenate([t, theta_u])
            if self.config.damping:  # the pose's poorly seen directions shrunk, as damped IBVS does (module docstring)
                error = self.shrunk(error, features_px)
            full = img.gain * error
            twist[img.cols] = full[img.cols]  # ibvs.PREDICT_DOFS' while predicting
        twist, saturated = bound_twist(twist, self.config.max_linear, self.config.max_angular)
        return ControlOutput(twist, img.error, img.error_px, img.gain, saturated, img.singular_values, self.dofs)
