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

from hvs_sim.control.features import (
    DEPTH_SOURCES,
    INTERACTION_AT,
    PointFeatures,
    condition_number,
    damped_pinv,
    matrix_rank,
    normalise,
)
from hvs_sim.control.protocol import DOF_NAMES, ControlInput
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.validate import check_number

SIMILARITY_DOFS = ("vx", "vy", "vz", "wz")  # what a similarity tracker's corners observe
CONTROLLERS = ("ibvs", "pbvs", "dvs")  # the built-in laws (dvs: photometric, control/laws/dvs.py)
# tracked corners' noise through L⁺ (cond ~540 at the goal) makes velocities the arm cannot follow: undamped the
# 6-DOF servo benchmark ended 10-17 px off. 0.005 held it but closed L's weak direction in ~4 s; with the averaged
# goal image and the feature filter (servo/loop.py) 0.002 closes it ~2.5× faster (tuned on episodes 300-305; README)
TRACKED_6DOF_DAMPING = 0.002


# the DOFs commanded while the tracker predicts (mode "predict"): its prediction moves the whole warp by a
# translation, which says nothing of pitch and yaw; on six DOF, commanding them from predicted corners drove the
# arm up to 0.5 m along L's weak direction through a long occlusion (servo benchmark, pause)
PREDICT_DOFS = SIMILARITY_DOFS


def dofs_for(warp: str) -> tuple[str, ...]:
    """The DOFs a tracker's corners observe: all six for perspective corners, four for a similarity."""
    return DOF_NAMES if warp == "homography" else SIMILARITY_DOFS


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


def scheduled_gain(config: IBVSConfig, err_inf: float) -> float:
    """λ for the largest feature error |e|∞: constant, or the adaptive gain from λ(0) to λ(∞) (IBVSConfig.gain_inf),
    as ViSP's vpAdaptiveGain. IBVS and PBVS share it."""
    if config.gain_inf is None:
        return config.gain
    d = config.gain - config.gain_inf
    return d * math.exp(-config.gain_slope * err_inf / d) + config.gain_inf


@dataclass(frozen=True)
class ImageTerms:
    """What a law on the points reads from the current features at a step: the error to s*, the gain it earns and
    the controlled columns of L (IBVS steers by them; PBVS reports them beside its pose error)."""

    error: np.ndarray  # (2N,) normalised s − s*
    error_px: float  # mean corner distance to s* (px)
    gain: float  # λ, times predict_gain while the tracker predicts
    cols: list[int]  # the columns of L commanded at this step (PREDICT_DOFS' while predicting)
    L: np.ndarray  # (2N, len(cols)) those columns
    singular_values: np.ndarray  # of L's controlled columns


def image_terms(points: PointFeatures, config: IBVSConfig, features_px, depths: np.ndarray | None, mode: str,
                cols: list[int], predict_cols: list[int]) -> ImageTerms:
    """The step's ImageTerms of the features (pixels): their error, depths (config.depth), L where config.interaction
    says, the scheduled gain."""
    s, e, err_px = points.error(features_px)
    L = points.matrix(s, points.depths(s, depths, config.depth), config.interaction)
    lam = scheduled_gain(config, float(np.abs(e).max()))
    if mode == "predict":
        lam *= config.predict_gain
    used = predict_cols if mode == "predict" else cols
    Lc = L[:, used]
    return ImageTerms(e, err_px, lam, used, Lc, np.linalg.svd(Lc, compute_uv=False))


class IBVSController:
    """Point-feature IBVS to fixed desired features s* (pixels), given intrinsics K."""

    def __init__(self, K: np.ndarray, desired_px: np.ndarray, desired_depth: float, config: IBVSConfig = IBVSConfig(),
                 dofs: tuple[str, ...] = SIMILARITY_DOFS):
        """`dofs`: the DOFs the features observe (dofs_for: the loop passes them), used when config.dofs is None."""
        self.points = PointFeatures(K, desired_px, desired_depth)
        self.K, self.desired_px, self.s_star = self.points.K, self.points.desired_px, self.points.s_star
        self.desired_depth, self.config = self.points.desired_depth, config
        self.dofs = tuple(config.dofs or dofs)
        self.cols = [DOF_NAMES.index(d) for d in self.dofs]
        self.predict_cols = [c for c in self.cols if DOF_NAMES[c] in PREDICT_DOFS]

    def normalise(self, px: np.ndarray) -> np.ndarray:
        return normalise(px, self.K)

    def gain(self, err_inf: float) -> float:
        return scheduled_gain(self.config, err_inf)

    def compute(self, features_px, depths: np.ndarray | None = None, mode: str = "align") -> ControlOutput:
        """Twist for the current features: a ControlInput (the law interface, control/protocol.py; its pixels and,
        with config.depth == 'true', its depths are read), or pixels with the true per-point depths when
        config.depth == 'true'."""
        if isinstance(features_px, ControlInput):
            inp = features_px
            features_px, depths, mode = inp.features_px, inp.depths, inp.mode
        img = image_terms(self.points, self.config, features_px, depths, mode, self.cols, self.predict_cols)
        twist = np.zeros(6)
        if mode != "lost":
            mu = (self.config.damping or 0.0) * img.singular_values.max()
            twist[img.cols] = -img.gain * (damped_pinv(img.L, mu) @ img.error)
        twist, saturated = bound_twist(twist, self.config.max_linear, self.config.max_angular)
        return ControlOutput(twist, img.error, img.error_px, img.gain, saturated, img.singular_values, self.dofs)


def bound_twist(twist: np.ndarray, max_linear: float, max_angular: float) -> tuple[np.ndarray, bool]:
    """Scale the whole twist under the per-axis bounds (keeps its direction); whether it was scaled."""
    limits = np.array([max_linear] * 3 + [max_angular] * 3)
    ratio = float(np.max(np.abs(twist) / limits))
    if ratio > 1.0:
        return twist / ratio, True
    return twist, False
