"""Image-based visual servoing with point features: v = −λ L⁺ e.

Features are the four tracked target corners in normalised image coordinates (x = (u − cx)/f).
Which DOFs are controlled follows what the features observe: true perspective corners (ground
truth, a homography tracker) observe all six; a similarity tracker observes translation, depth and
roll of the target but not its pitch and yaw, so with it only (vx, vy, vz, ωz) are controlled and
ωx, ωy are commanded zero (`dofs_for`). Each step reports the singular values of the controlled
columns of L (rank and condition number), as ViSP users check them.
Twists are in the camera frame, OpenCV convention (x right, y down, z forward).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from hvs_sim.control.protocol import DOF_NAMES, ControlInput, rms_size, scale_depths
from hvs_sim.errors import ConfigError, InputError, choice_error
from hvs_sim.validate import check_number

SIMILARITY_DOFS = ("vx", "vy", "vz", "wz")  # what a similarity tracker's corners observe
RANK_TOL = 1e-6  # singular values below this × the largest count as zero (rank of L)
CONTROLLERS = ("ibvs", "pbvs", "dvs")  # the built-in laws (dvs: photometric, control/dvs.py)
# tracked corners' noise through L⁺ (cond ~540 at the goal) makes velocities the arm cannot follow: undamped the
# 6-DOF servo benchmark ended 10-17 px off. 0.005 held it but closed L's weak direction in ~4 s; with the averaged
# goal image and the feature filter (servo/loop.py) 0.002 closes it ~2.5× faster (tuned on episodes 300-305; README)
TRACKED_6DOF_DAMPING = 0.002


# the DOFs commanded while the tracker predicts (mode "predict"): its prediction moves the whole warp by a
# translation, which says nothing of pitch and yaw; on six DOF, commanding them from predicted corners drove the
# arm up to 0.5 m along L's weak direction through a long occlusion (servo benchmark, pause)
PREDICT_DOFS = SIMILARITY_DOFS
INTERACTION_AT = ("current", "desired", "mean")
DEPTH_SOURCES = ("scale", "true")


def dofs_for(warp: str) -> tuple[str, ...]:
    """The DOFs a tracker's corners observe: all six for perspective corners, four for a similarity."""
    return DOF_NAMES if warp == "homography" else SIMILARITY_DOFS


def matrix_rank(sv: np.ndarray) -> int | None:
    """Rank from singular values (RANK_TOL relative to the largest); None when there are none."""
    return int((sv > RANK_TOL * sv.max()).sum()) if len(sv) and sv.max() > 0 else (0 if len(sv) else None)


def condition_number(sv: np.ndarray) -> float | None:
    """σ_max / σ_min; None when there are no singular values or the smallest is zero (rank-deficient)."""
    return float(sv.max() / sv.min()) if len(sv) and sv.min() > 0 else None


MIN_DESIRED_SPREAD_PX = 1.0  # desired points closer together than this make L singular


def interaction_matrix(xy: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Stacked 2×6 interaction matrices of normalised points xy (N, 2) at depths Z (N,)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    Z = np.broadcast_to(np.asarray(Z, float), (len(xy),))
    x, y = xy[:, 0], xy[:, 1]
    L = np.zeros((2 * len(xy), 6))
    L[0::2] = np.stack([-1 / Z, 0 * x, x / Z, x * y, -(1 + x * x), y], 1)
    L[1::2] = np.stack([0 * x, -1 / Z, y / Z, 1 + y * y, -x * y, -x], 1)
    return L


@dataclass(frozen=True)
class IBVSConfig:
    """Gain, interaction-matrix choice and controlled DOFs. Adaptive gain when lambda_inf is set."""

    gain: float = 2.0  # λ (1/s), or λ(0) for the adaptive gain
    gain_inf: float | None = None  # λ(∞); None = constant gain
    gain_slope: float = 30.0  # λ'(0), slope of the adaptive gain at zero error
    interaction: str = "mean"
    depth: str = "scale"
    dofs: tuple[str, ...] | None = None  # None: what the features observe (dofs_for; the loop decides)
    predict_gain: float = 0.5  # multiplies λ while the tracker predicts (occlusion)
    max_linear: float = 0.15  # m/s, per-axis command bound (reported when hit)
    max_angular: float = 0.6  # rad/s
    # damped pseudo-inverse (LᵀL + μ²I)⁻¹Lᵀ with μ = damping × σ_max(L); 0 = the plain L⁺ of the paper (PBVS weights
    # its pose error by the same (LᵀL + μ²I)⁻¹LᵀL: pbvs.PBVSController.shrunk).
    # Damps the directions L barely sees (pitch/yaw against lateral shift for a small target), whose
    # velocity would otherwise be tracker noise divided by a small singular value. None: the loop
    # decides (TRACKED_6DOF_DAMPING for tracked features on six DOF, else 0; README, servo benchmark)
    damping: float | None = None

    def __post_init__(self):
        check_number("gain", self.gain, 0, lo_open=True)
        if self.gain_inf is not None:
            check_number("gain_inf", self.gain_inf, 0, self.gain, lo_open=True, hi_open=True)
        check_number("gain_slope", self.gain_slope, 0, lo_open=True)
        if self.interaction not in INTERACTION_AT:
            raise choice_error("interaction matrix evaluation", self.interaction, INTERACTION_AT)
        if self.depth not in DEPTH_SOURCES:
            raise choice_error("depth source", self.depth, DEPTH_SOURCES)
        if self.dofs is not None and (not self.dofs or any(d not in DOF_NAMES for d in self.dofs)):
            raise ConfigError(f"dofs {self.dofs} invalid; accepted: a subset of {', '.join(DOF_NAMES)}")
        check_number("predict_gain", self.predict_gain, 0, 1)
        check_number("max_linear (m/s)", self.max_linear, 0, lo_open=True)
        check_number("max_angular (rad/s)", self.max_angular, 0, lo_open=True)
        if self.damping is not None:
            check_number("damping", self.damping, 0, 1)


@dataclass
class ControlOutput:
    twist: np.ndarray  # (6,) camera frame
    error: np.ndarray  # (2N,) normalised feature error s − s*
    error_px: float  # mean corner distance to s* in pixels (what the controller sees)
    gain: float
    saturated: bool
    singular_values: np.ndarray = field(default_factory=lambda: np.zeros(0))  # of the controlled columns of L
    dofs: tuple[str, ...] | None = None  # the DOFs commanded (None: the law's own `dofs`)

    @property
    def rank(self) -> int:
        return matrix_rank(self.singular_values) or 0

    @property
    def condition(self) -> float:
        """Condition number of the controlled columns of L (inf when rank-deficient)."""
        c = condition_number(self.singular_values)
        return float("inf") if c is None else c


class Law(Protocol):
    """A servo law as the loop drives it on one template's s*: the built-ins, and an outside law once bounded
    (servo/laws.py's OutsideLaw)."""

    def compute(self, inp: ControlInput, /) -> ControlOutput: ...


class IBVSController:
    """Point-feature IBVS to fixed desired features s* (pixels), given intrinsics K."""

    def __init__(self, K: np.ndarray, desired_px: np.ndarray, desired_depth: float, config: IBVSConfig = IBVSConfig(),
                 dofs: tuple[str, ...] = SIMILARITY_DOFS):
        """`dofs`: the DOFs the features observe (dofs_for: the loop passes them), used when config.dofs is None."""
        try:
            self.K = np.asarray(K, float)
            self.desired_px = np.asarray(desired_px, float).reshape(-1, 2)
        except (TypeError, ValueError):
            raise InputError("K must be a 3×3 intrinsic matrix and desired_px N×2 pixels (N >= 3)") from None
        if self.K.shape != (3, 3) or not np.isfinite(self.K).all() or self.K[0, 0] <= 0 or self.K[1, 1] <= 0:
            raise InputError(f"K must be a finite 3×3 intrinsic matrix with fx, fy > 0, got {self.K.tolist()}")
        if len(self.desired_px) < 3 or not np.isfinite(self.desired_px).all():
            raise InputError(f"desired_px must be at least 3 finite points (N×2 pixels), got {len(self.desired_px)}")
        if np.ptp(self.desired_px, axis=0).max() < MIN_DESIRED_SPREAD_PX:
            raise InputError(f"desired_px points coincide (spread < {MIN_DESIRED_SPREAD_PX} px): the interaction matrix "
                             "would be singular; give distinct target corners")
        self.config = config
        if not (np.isfinite(desired_depth) and desired_depth > 0):
            raise ConfigError(f"desired depth must be > 0 m, got {desired_depth}")
        self.desired_depth = float(desired_depth)
        self.s_star = self.normalise(self.desired_px)
        self.dofs = tuple(config.dofs or dofs)
        self.cols = [DOF_NAMES.index(d) for d in self.dofs]
        self.predict_cols = [c for c in self.cols if DOF_NAMES[c] in PREDICT_DOFS]

    def normalise(self, px: np.ndarray) -> np.ndarray:
        K = self.K
        return np.stack([(px[:, 0] - K[0, 2]) / K[0, 0], (px[:, 1] - K[1, 2]) / K[1, 1]], 1)

    def gain(self, err_inf: float) -> float:
        c = self.config
        if c.gain_inf is None:
            return c.gain
        d = c.gain - c.gain_inf
        return d * math.exp(-c.gain_slope * err_inf / d) + c.gain_inf

    scale_of = staticmethod(rms_size)

    def compute(self, features_px, depths: np.ndarray | None = None, mode: str = "align") -> ControlOutput:
        """Twist for the current features: a ControlInput (the law interface, control/protocol.py; its pixels and,
        with config.depth == 'true', its depths are read), or pixels with the true per-point depths when
        config.depth == 'true'."""
        if isinstance(features_px, ControlInput):
            inp = features_px
            features_px, depths, mode = inp.features_px, inp.depths, inp.mode
        f = np.asarray(features_px, float).reshape(-1, 2)
        if f.shape != self.desired_px.shape or not np.isfinite(f).all():
            raise InputError(f"features must be finite pixels of shape {self.desired_px.shape}, got {f.shape}")
        s = self.normalise(f)
        e = (s - self.s_star).reshape(-1)
        err_px = float(np.linalg.norm(f - self.desired_px, axis=1).mean())
        if self.config.depth == "true":
            if depths is None or not np.all(np.asarray(depths) > 0):
                raise InputError("depth='true' needs positive per-point depths from the simulator")
            Z = np.asarray(depths, float)
        else:  # depth from apparent size: Z = Z* · size(s*) / size(s)
            Z = scale_depths(s, self.s_star, self.desired_depth)
        Zs = np.full(len(f), self.desired_depth)
        if self.config.interaction == "current":
            L = interaction_matrix(s, Z)
        elif self.config.interaction == "desired":
            L = interaction_matrix(self.s_star, Zs)
        else:
            L = 0.5 * (interaction_matrix(s, Z) + interaction_matrix(self.s_star, Zs))
        lam = self.gain(float(np.abs(e).max()))
        if mode == "predict":
            lam *= self.config.predict_gain
        twist = np.zeros(6)
        cols = self.predict_cols if mode == "predict" else self.cols
        Lc = L[:, cols]
        sv = np.linalg.svd(Lc, compute_uv=False)
        if mode != "lost":
            twist[cols] = -lam * (damped_pinv(Lc, (self.config.damping or 0.0) * sv.max()) @ e)
        twist, saturated = bound_twist(twist, self.config.max_linear, self.config.max_angular)
        return ControlOutput(twist, e, err_px, lam, saturated, sv, self.dofs)


def damped_pinv(L: np.ndarray, mu: float) -> np.ndarray:
    """(LᵀL + μ²I)⁻¹Lᵀ through the SVD (L⁺ when μ = 0)."""
    if mu <= 0:
        return np.linalg.pinv(L)
    U, sv, Vt = np.linalg.svd(L, full_matrices=False)
    return (Vt.T * (sv / (sv ** 2 + mu ** 2))) @ U.T


def bound_twist(twist: np.ndarray, max_linear: float, max_angular: float) -> tuple[np.ndarray, bool]:
    """Scale the whole twist under the per-axis bounds (keeps its direction); whether it was scaled."""
    limits = np.array([max_linear] * 3 + [max_angular] * 3)
    ratio = float(np.max(np.abs(twist) / limits))
    if ratio > 1.0:
        return twist / ratio, True
    return twist, False
