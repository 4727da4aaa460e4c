"""Deep LK: global NCC match → patch → frozen VGG-16 features → inverse-compositional LK.

Everything runs on a grey working image at `scale` of the frame (the paper resizes frames for
speed; 0.5 keeps VGG at ~5 ms on two CPU cores). Poses are reported at full resolution.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
import torch

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.base import Estimate, Tracker
from hvs_sim.tracking.feature_lk import FeatureICLK, LKConfig
from hvs_sim.tracking.frames import to_grey
from hvs_sim.tracking.global_match import GlobalMatcher
from hvs_sim.tracking.nets.vgg import vgg16_pool2
from hvs_sim.tracking.occlusion import TAU_PIX, aligned_patch, occlusion_fraction
from hvs_sim.tracking.warp import apply, matrix_to_pose, pose_to_matrix


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
    # rejected (LK pulled by an occluder); a real 30 Hz camera does not move that fast
    max_rotation_step: float = 0.1  # rad (5.7°)
    max_scale_step: float = 0.08
    device: str = "cpu"
    weights: str | None = None  # VGG weights path (.npz of hvs_sim or torchvision's .pth); None = shipped
    residual: bool = False  # refine the LK estimate with the residual regressor (the paper's "Deep LK+Δ")
    residual_weights: str | None = None  # None = shipped assets/weights/residual.pt

    def __post_init__(self):
        if not 0.2 <= self.scale <= 1.0:
            raise ConfigError(f"scale must be in [0.2, 1.0], got {self.scale}")
        if not 0 < self.match_threshold < 1:
            raise ConfigError(f"match_threshold must be in (0, 1), got {self.match_threshold}")


class DeepLKTracker(Tracker):
    """The paper's "Deep LK" baseline and the alignment engine of the hybrid tracker."""

    name = "deep_lk"

    def __init__(self, config: DeepLKConfig = DeepLKConfig()):
        super().__init__()
        self.config = config
        self.device = select_device(config.device)
        self.net = vgg16_pool2(config.weights).to(self.device)
        self.matcher = GlobalMatcher()
        self.lk = FeatureICLK(config.lk)
        self.residual_net = None
        if config.residual:
            if "pool2" not in config.lk.levels:
                raise ConfigError("the residual regressor needs the pool2 LK level")
            from hvs_sim.tracking.nets.residual import load_residual

            self.residual_net = load_residual(config.residual_weights).to(self.device)
        s = config.scale
        self.S = np.array([[s, 0, 0.5 * s - 0.5], [0, s, 0.5 * s - 0.5], [0, 0, 1.0]])  # full → work pixels
        self.S_inv = np.linalg.inv(self.S)

    # ----------------------------------------------------------------- helpers

    def work_image(self, frame: np.ndarray) -> np.ndarray:
        grey = to_grey(frame)
        if self.config.scale == 1.0:
            return grey
        return cv2.resize(grey, None, fx=self.config.scale, fy=self.config.scale, interpolation=cv2.INTER_AREA)

    def features(self, work: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> dict[str, torch.Tensor]:
        crop = np.ascontiguousarray(work[y0:y1, x0:x1], np.float32)
        with torch.inference_mode():
            out = self.net(torch.from_numpy(crop)[None, None].to(self.device), levels=self.config.lk.levels)
        return {k: v[0].float().cpu() for k, v in out.items()}

    def _crop_box(self, corners_work: np.ndarray, shape) -> tuple[int, int, int, int]:
        m = self.config.margin
        x0 = max(0, int(np.floor(corners_work[:, 0].min())) - m)
        y0 = max(0, int(np.floor(corners_work[:, 1].min())) - m)
        x1 = min(shape[1], int(np.ceil(corners_work[:, 0].max())) + m + 1)
        y1 = min(shape[0], int(np.ceil(corners_work[:, 1].max())) + m + 1)
        return x0, y0, x1, y1

    def to_work(self, A_full: np.ndarray) -> np.ndarray:
        return self.S @ A_full @ self.S_inv

    def to_full(self, A_work: np.ndarray) -> np.ndarray:
        return self.S_inv @ A_work @ self.S

    # ----------------------------------------------------------------- contract

    def _init(self, frame, roi) -> None:
        work = self.work_image(frame)
        x, y, w, h = roi
        s = self.config.scale
        self.c_work = apply(self.S, self.center0[None])[0]
        self.tw, self.th = max(8, int(round(w * s))), max(8, int(round(h * s)))
        self.t_origin = self.c_work - np.array([(self.tw - 1) / 2.0, (self.th - 1) / 2.0])
        self.template, _ = aligned_patch(work, np.eye(3), self.t_origin, (self.th, self.tw))
        self.init_work = work  # the template's view, to rectify the search template by the current θ, s
        self.search_template, self._rectified_for = self.template, (0.0, 1.0)
        self.rho = max(self.tw, self.th) / 2.0
        self.N = np.array([[1 / self.rho, 0, -self.c_work[0] / self.rho], [0, 1 / self.rho, -self.c_work[1] / self.rho], [0, 0, 1]])
        self.N_inv = np.linalg.inv(self.N)
        # centres of the template's corner pixels (work px): what the crop around a warp must hold
        self.t_corners = self.t_origin + np.array([[0, 0], [self.tw - 1, 0], [self.tw - 1, self.th - 1], [0, self.th - 1]])
        x0, y0, x1, y1 = self._crop_box(self.t_corners, work.shape)
        feats = self.features(work, x0, y0, x1, y1)
        lo, hi = self.t_origin - 0.5, self.t_origin + np.array([self.tw - 0.5, self.th - 0.5])
        self.lk.set_template(feats, np.array([x0, y0], float), self.c_work, self.rho, (lo, hi))

    def coarse(self, work: np.ndarray, keep_current: bool = True):
        """Global match, and the work-resolution warp to start from (θ, s kept from the last pose).

        Two candidates: the current estimate, and the current estimate moved to the global match's
        centre. OP_t is measured on the patch each of them aligns, and the one showing the target
        best (lowest OP_t) wins: under partial occlusion the NCC peak can jump to another place
        while the current estimate still sits on the visible part of the target.
        The search uses the template rectified by the current θ, s and the template as taken; a
        match of the latter seeds θ = 0, s = 1. With keep_current=False (the paper's Deep LK
        baseline) only global-match seeds are considered.
        Returns (match, seed warp, OP_t at the seed, whether the seed is the current estimate).
        """
        A_prev = self.to_work(self.A)
        rectified = self.rectified_template()
        matches = [(self.matcher.match(work, rectified), A_prev)]
        if rectified is not self.template:  # also the template as taken, in case θ, s went wrong
            matches.append((self.matcher.match(work, self.template), np.eye(3)))
        m = max(matches, key=lambda mk: mk[0].score)[0]
        c_prev = apply(A_prev, self.c_work[None])[0]
        seeds = []
        for match, A_shape in matches:
            if not np.all(np.isfinite(match.center)):
                continue
            if A_shape is A_prev and np.linalg.norm(match.center - c_prev) <= self.config.reinit_px:
                seeds.append((match, A_prev))  # agrees with the current estimate: keep its sub-pixel pose
                continue
            seed = A_shape.copy()
            seed[:2, 2] += match.center - apply(A_shape, self.c_work[None])[0]
            seeds.append((match, seed))
        if keep_current:
            candidates = [A_prev] + [sd for _, sd in seeds if sd is not A_prev]
        else:
            candidates = [sd for match, sd in seeds if match is m] or [A_prev]
        best = None
        for A in candidates:
            op = self.occlusion(work, A)
            if best is None or op < best[1]:
                best = (A, op)
        A, op = best
        return m, A, op, A is A_prev

    def rectified_template(self) -> np.ndarray:
        """The template as it should look now: the init view rotated and scaled by the current θ, s.

        NCC is not invariant to rotation and scale; while servoing the target grows or shrinks by
        10 % and more, which would drag the score under the 0.6 gate. Re-made when θ or s moved
        by more than 0.5° or 1 %.
        """
        _, _, theta, scale = matrix_to_pose(self.A, self.center0)
        t0, s0 = self._rectified_for
        if abs(theta - t0) > np.radians(0.5) or abs(scale / s0 - 1) > 0.01:
            # a template pixel q (about the centre c) shows init-view point c + R(−θ)(q − c)/s
            A = pose_to_matrix((0.0, 0.0, -theta, 1.0 / scale), self.c_work)
            self.search_template, _ = aligned_patch(self.init_work, A, self.t_origin, (self.th, self.tw))
            self._rectified_for = (theta, scale)
        return self.search_template

    def occlusion(self, work: np.ndarray, A_work: np.ndarray) -> float:
        patch, inside = aligned_patch(work, A_work, self.t_origin, (self.th, self.tw))
        return occlusion_fraction(patch, self.template, inside, self.config.tau_pix)

    def residual_inputs(self, feats, origin, M) -> tuple[torch.Tensor, torch.Tensor]:
        """(256, rows, cols) template ⊕ aligned pool2 features and the warp [tx/ρ, ty/ρ, θ, s − 1].

        Both feature maps are divided by the template's mean activation, so the regressor sees the
        same scale whatever the flag's contrast.
        """
        template = self.lk.template_grid("pool2")
        scale = template.mean().clamp_min(1e-6)
        stacked = torch.cat([template, self.lk.aligned_grid(feats, origin, M, "pool2")], 0) / scale
        pose = matrix_to_pose(M, (0.0, 0.0))  # normalised coordinates: centre at 0, unit ρ
        warp = torch.tensor([pose[0], pose[1], pose[2], pose[3] - 1.0], dtype=torch.float32)
        return stacked, warp

    def refine(self, feats, origin, M) -> np.ndarray:
        """Apply the regressor's Δp (ρ-scaled units, see nets/residual.py) to the LK warp M."""
        stacked, warp = self.residual_inputs(feats, origin, M)
        with torch.inference_mode():
            d = self.residual_net(stacked[None].to(self.device), warp[None].to(self.device))[0].cpu().double().numpy()
        pose = matrix_to_pose(M, (0.0, 0.0))
        pose = pose + np.array([d[0], d[1], d[2], d[3]]) / self.rho
        return pose_to_matrix(pose, (0.0, 0.0))

    def run_lk(self, work: np.ndarray, A_work: np.ndarray):
        """Plain feature LK from A_work on a crop around it: (AlignResult, crop features, crop origin),
        or None when the crop is too small (target off the frame)."""
        x0, y0, x1, y1 = self._crop_box(apply(A_work, self.t_corners), work.shape)
        if x1 - x0 < 16 or y1 - y0 < 16:
            return None
        feats = self.features(work, x0, y0, x1, y1)
        origin = np.array([x0, y0], float)
        return self.lk.align(feats, origin, (y1 - y0, x1 - x0), self.N @ A_work @ self.N_inv), feats, origin

    def align(self, work: np.ndarray, A_work: np.ndarray):
        """Feature LK (+ residual) from A_work; returns (work warp, or None when it failed, AlignResult)."""
        out = self.run_lk(work, A_work)
        if out is None:
            return None, None
        res, feats, origin = out
        if self.residual_net is not None and np.all(np.isfinite(res.M)):
            res.M = self.refine(feats, origin, res.M)
        A_new = self.N_inv @ res.M @ self.N
        scale = np.sqrt(abs(np.linalg.det(A_new[:2, :2])))
        moved = np.linalg.norm(apply(A_new, self.c_work[None]) - apply(A_work, self.c_work[None]))
        _, _, d_theta, d_scale = matrix_to_pose(np.linalg.solve(A_work, A_new), self.c_work)
        jump = abs(d_theta) > self.config.max_rotation_step or abs(d_scale - 1) > self.config.max_scale_step
        if not np.all(np.isfinite(A_new)) or not 0.5 < scale < 2.0 or moved > self.rho or res.valid < 0.3 or jump:
            return None, res
        return A_new, res

    def _update(self, frame) -> Estimate:
        work = self.work_image(frame)
        m, A_work, _, _ = self.coarse(work, keep_current=False)
        if m.score <= 0.0:
            return Estimate(self.A, "lost", 1.0, m.score)
        A_new, _ = self.align(work, A_work)
        if A_new is None:
            return Estimate(self.A, "lost", self.occlusion(work, A_work), m.score)
        return Estimate(self.to_full(A_new), "align", self.occlusion(work, A_new), m.score)


