"""The alignment engine's settings (`DeepLKConfig`) and the torch device it runs on: apart from aligner.py so that
the configs that hold one (hybrid_config.py) need not import the engine."""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.feature_lk import LKConfig
from hvs_sim.tracking.intensity_ic import SMOOTH_MODES
from hvs_sim.tracking.occlusion import TAU_PIX
from hvs_sim.tracking.trackability import MIN_TRACKABILITY
from hvs_sim.tracking.warp import check_warp
from hvs_sim.validate import check_flags, check_number


def select_device(device: str) -> torch.device:
    if device == "cpu":
        return torch.device("cpu")
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if device == "cuda":
        if not torch.cuda.is_available():
            raise ConfigError("device 'cuda' asked for but torch sees no CUDA device; accepted here: cpu, auto")
        return torch.device("cuda")
    raise ConfigError(f"unknown device {device!r}; accepted: cpu, cuda, auto")


@dataclass(frozen=True)
class DeepLKConfig:
    scale: float = 0.5  # working resolution relative to the frame
    match_threshold: float = 0.6
    tau_pix: float = TAU_PIX
    lk: LKConfig = field(default_factory=LKConfig)
    margin: int = 8  # work px of context around the template / patch
    reinit_px: float = 2.0  # re-seed from the global match when it disagrees by more than this (work px)
    # an alignment that turns or scales the target more than this from its seed in one frame is
    # rejected (LK pulled by an occluder); a real 30 Hz camera does not move that fast. From an estimate
    # whose θ and s were last measured n frames ago, n times this (Aligner.align's `frames`)
    max_rotation_step: float = 0.1  # rad (5.7°)
    max_scale_step: float = 0.08
    device: str = "cpu"
    weights: str | None = None  # VGG weights path (.npz of hvs_sim or torchvision's .pth); None = shipped
    residual: bool = False  # refine the LK estimate with the residual regressor (the paper's "Deep LK+Δ")
    residual_weights: str | None = None  # None = shipped assets/weights/residual.pt
    # keep the residual's correction only when it lowers the feature-space alignment cost (False:
    # always apply it, as the paper does)
    verify_residual: bool = True
    # init refuses a template with less texture than this (tracking/trackability.py); with
    # allow_untrackable it is tracked anyway and every Track's confidence says how little to trust it
    min_trackability: float = MIN_TRACKABILITY
    allow_untrackable: bool = False
    # OP_t after scaling the template by the frame's exposure gain (occlusion.py; False: raw
    # intensities, as the paper)
    normalise_exposure: bool = True
    # the feature LK sees the frame scaled to the template's exposure (Aligner.lk; False: as it comes, as the
    # paper): VGG features are not invariant to a gain, and on a low-contrast target a 20 % exposure drift
    # moved LK's optimum by 6–15 px
    normalise_lk_exposure: bool = True
    # the warp the feature LK estimates: "similarity" (the paper's: translation, roll, scale) or
    # "homography" (a plane in perspective: its four corners are true perspective corners, so a
    # servo loop can control all six DOF)
    warp: str = "similarity"
    # homography only: refine LK's answer on the full-resolution grey template (refine_intensity, intensity_ic.py)
    refine_intensity: bool = True
    # ... smoothing the frame on the template's grid ("template") or in its own pixels ("frame"; the hybrid's):
    # intensity_ic.SMOOTH_MODES says what each measured
    intensity_smooth: str = "template"
    # search with the template as taken on every frame, beside the template rectified by the current θ, s
    # (False, the hybrid's default: only when the rectified search does not confirm an unhidden estimate;
    # see Aligner.coarse)
    always_search_as_taken: bool = True
    # search the rectified template near the current estimate first, and skip the global searches when
    # that confirms an unhidden estimate (True, the hybrid's default; see Aligner.coarse)
    search_near_first: bool = False

    def __post_init__(self):
        check_warp(self.warp)
        if not isinstance(self.lk, LKConfig):
            raise ConfigError(f"lk must be an LKConfig (or, through make_tracker, a dict of its settings), got "
                              f"{type(self.lk).__name__}")
        check_flags(self, ("residual", "verify_residual", "allow_untrackable", "normalise_exposure", "refine_intensity",
                           "normalise_lk_exposure", "always_search_as_taken", "search_near_first"))
        if self.intensity_smooth not in SMOOTH_MODES:
            raise ConfigError(f"intensity_smooth must be one of {', '.join(SMOOTH_MODES)}, got {self.intensity_smooth!r}")
        if self.residual and self.warp != "similarity":
            raise ConfigError("the residual regressor predicts a similarity correction; it cannot refine a "
                              f"{self.warp} warp: use residual=False with warp={self.warp!r}")
        if not 0.2 <= self.scale <= 1.0:
            raise ConfigError(f"scale must be in [0.2, 1.0], got {self.scale}")
        if not 0 < self.match_threshold < 1:
            raise ConfigError(f"match_threshold must be in (0, 1), got {self.match_threshold}")
        check_number("tau_pix", self.tau_pix, 0, 255, lo_open=True)
        check_number("margin", self.margin, 0, integer=True)
        check_number("reinit_px", self.reinit_px, 0, lo_open=True)
        check_number("max_rotation_step", self.max_rotation_step, 0, lo_open=True)
        check_number("max_scale_step", self.max_scale_step, 0, lo_open=True)
        check_number("min_trackability", self.min_trackability, 0)
