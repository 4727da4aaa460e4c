"""Inverse-compositional Lucas–Kanade (Baker & Matthews) for a similarity or homography warp on feature maps.

Coordinates are centred on the template and divided by ρ (half its larger side), so the
parameters are of one scale: the four p = (a, b, tx, ty) of the similarity
W(x̃; p) = [[1 + a, −b, tx], [b, 1 + a, ty]] (the paper's), or the eight of the homography
[[1 + p1, p2, p3], [p4, 1 + p5, p6], [p7, p8, 1]] (a plane seen in perspective: pitch and yaw of
the target change its shape, which a similarity cannot follow).
The steepest-descent images and the per-point Gauss–Newton Hessians are computed once per
template; every iteration samples the image features at the warped template points, solves a
4×4 (8×8) system and composes the inverse update: W ← W ∘ W(Δp)⁻¹.

Feature maps of stride σ (pool2: 4, pool1: 2, conv1_2: 1) cover input pixels σi … σi + σ − 1, so
feature index i sits at pixel σi + (σ − 1)/2 of the crop it was computed on.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.nets.vgg import STRIDES
from hvs_sim.tracking.warp import WARP_PARAMS, apply, check_warp, homography_params_to_matrix, params_to_matrix

HUBER_K = 1.345  # Huber threshold in robust standard deviations (95 % efficiency on Gaussian residuals)
MAD_TO_SIGMA = 1.4826  # median absolute deviation → standard deviation
_UNIT_BOX = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])  # normalised template extent


def warp_jacobian(pts: np.ndarray, warp: str) -> tuple[np.ndarray, np.ndarray]:
    """dx'/dp and dy'/dp (N, P) of the warp at the identity, at normalised template points."""
    x, y = pts[:, 0], pts[:, 1]
    one, zero = np.ones(len(pts)), np.zeros(len(pts))
    if warp == "similarity":  # x' = (1+a)x − b y + tx, y' = b x + (1+a) y + ty
        return np.stack([x, -y, one, zero], 1), np.stack([y, x, zero, one], 1)
    # x' = ((1+p1)x + p2 y + p3) / (p7 x + p8 y + 1), y' = (p4 x + (1+p5) y + p6) / (p7 x + p8 y + 1)
    return (np.stack([x, y, one, zero, zero, zero, -x * x, -x * y], 1),
            np.stack([zero, zero, zero, x, y, one, -x * y, -y * y], 1))


def update_matrix(dp: np.ndarray, warp: str) -> np.ndarray:
    return params_to_matrix(dp) if warp == "similarity" else homography_params_to_matrix(dp)


@dataclass(frozen=True)
class LKConfig:
    """Coarse-to-fine schedule and stopping rule of the feature LK."""

    levels: tuple[str, ...] = ("pool2", "pool1", "conv1_2")
    iterations: tuple[int, ...] = (15, 10, 8)
    eps: float = 2e-3  # stop a level when the update moves template points by < eps × stride (work px)
    border: float = 3.0  # work px: image features nearer the crop edge than this are not used
    robust: bool = True  # Huber weights per template point, so partial occlusion weighs less

    def __post_init__(self):
        bad = [lv for lv in self.levels if lv not in STRIDES]
        if bad or not self.levels:
            raise ConfigError(f"LK levels {self.levels} invalid; accepted: a sequence of {', '.join(STRIDES)}")
        if len(self.iterations) != len(self.levels) or min(self.iterations) < 1:
            raise ConfigError("LK iterations must give one positive count per level")


def sample_points(fmap: torch.Tensor, pts: np.ndarray, origin: np.ndarray, stride: int) -> tuple[torch.Tensor, np.ndarray]:
    """Bilinear feature samples (N, C) at work-pixel points, and the feature-grid coordinates used."""
    u = (pts - origin - (stride - 1) / 2.0) / stride
    _, Hf, Wf = fmap.shape
    g = torch.from_numpy(np.stack([2 * u[:, 0] / max(Wf - 1, 1) - 1, 2 * u[:, 1] / max(Hf - 1, 1) - 1], 1)).float()
    out = F.grid_sample(fmap[None], g[None, None], mode="bilinear", padding_mode="border", align_corners=True)
    return out[0, :, 0].T, u


@dataclass
class _Level:
    name: str
    stride: int
    pts: np.ndarray  # (N, 2) normalised template coordinates
    feats: torch.Tensor  # (N, C) template features
    sd: torch.Tensor  # (N·C, P) steepest-descent images, point-major (P = 4 similarity, 8 homography)
    hess: np.ndarray  # (N, P²) per-point Gauss–Newton Hessians, flattened
    grid: tuple[int, int]  # the points form this (rows, cols) block of feature cells, row-major


@dataclass
class AlignResult:
    M: np.ndarray  # final warp in normalised coordinates
    iterations: int
    valid: float  # share of template points that landed inside the image crop (last level)
    residual: float  # RMS feature residual of the valid points (last level)
    per_level: list = field(default_factory=list)


class FeatureICLK:
    """IC-LK of one template; `align` is called once per frame with that frame's feature maps."""

    def __init__(self, config: LKConfig = LKConfig(), warp: str = "similarity"):
        self.config, self.warp, self.n_params = config, check_warp(warp), WARP_PARAMS[warp]
        self.levels: list[_Level] = []

    def set_template(self, feats: dict[str, torch.Tensor], origin: np.ndarray, center: np.ndarray, rho: float,
                     rect: tuple[np.ndarray, np.ndarray]) -> None:
        """Feature maps of a crop whose top-left pixel is at work coords `origin`; template = `rect` (lo, hi)."""
        self.center, self.rho = np.asarray(center, float), float(rho)
        lo, hi = rect
        self.template_maps, self.template_origin = feats, np.asarray(origin, float)  # kept for diagnostics
        self.levels = []
        for name in self.config.levels:
            fmap = feats[name][0] if feats[name].dim() == 4 else feats[name]
            s = STRIDES[name]
            _, Hf, Wf = fmap.shape
            jj, ii = np.meshgrid(np.arange(1, Wf - 1), np.arange(1, Hf - 1))
            px = np.stack([origin[0] + s * jj + (s - 1) / 2.0, origin[1] + s * ii + (s - 1) / 2.0], -1).reshape(-1, 2)
            inside = (px[:, 0] >= lo[0]) & (px[:, 0] <= hi[0]) & (px[:, 1] >= lo[1]) & (px[:, 1] <= hi[1])
            ii, jj, px = ii.reshape(-1)[inside], jj.reshape(-1)[inside], px[inside]
            grid = (len(np.unique(ii)), len(np.unique(jj)))
            if len(px) < 6:
                raise ConfigError(f"template too small for LK level {name}: {len(px)} feature points")
            f = fmap[:, ii, jj].T.contiguous()  # (N, C)
            gx = (fmap[:, ii, jj + 1] - fmap[:, ii, jj - 1]).T / (2.0 * s)  # per work pixel
            gy = (fmap[:, ii + 1, jj] - fmap[:, ii - 1, jj]).T / (2.0 * s)
            pts = (px - self.center) / self.rho
            jx, jy = (torch.from_numpy(j).float() for j in warp_jacobian(pts, self.warp))
            sd = (gx * self.rho)[:, :, None] * jx[:, None, :] + (gy * self.rho)[:, :, None] * jy[:, None, :]
            P = self.n_params
            hess = torch.einsum("nci,ncj->nij", sd, sd).double().numpy().reshape(-1, P * P)
            self.levels.append(_Level(name, s, pts, f, sd.reshape(-1, P).contiguous(), hess, grid))

    def level(self, name: str) -> _Level:
        return next(lv for lv in self.levels if lv.name == name)

    def template_grid(self, name: str) -> torch.Tensor:
        """Template features of a level as a (C, rows, cols) map."""
        lv = self.level(name)
        return lv.feats.T.reshape(-1, *lv.grid)

    def aligned_grid(self, feats: dict[str, torch.Tensor], origin: np.ndarray, M: np.ndarray, name: str) -> torch.Tensor:
        """Image features sampled at the warped template points, as a (C, rows, cols) map."""
        lv = self.level(name)
        fmap = feats[name][0] if feats[name].dim() == 4 else feats[name]
        sampled, _ = sample_points(fmap, self.to_work(M, lv.pts), origin, lv.stride)
        return sampled.T.reshape(-1, *lv.grid)

    def residuals(self, feats: dict[str, torch.Tensor], origin: np.ndarray, M: np.ndarray,
                  name: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Per-point feature residual norms of the normalised warp M on a level (default: the
        finest), and which points fall inside the feature map."""
        lv = self.levels[-1] if name is None else self.level(name)
        fmap = feats[lv.name][0] if feats[lv.name].dim() == 4 else feats[lv.name]
        sampled, u = sample_points(fmap, self.to_work(M, lv.pts), origin, lv.stride)
        inside = (u[:, 0] >= 0) & (u[:, 0] <= fmap.shape[2] - 1) & (u[:, 1] >= 0) & (u[:, 1] <= fmap.shape[1] - 1)
        return torch.linalg.vector_norm(sampled - lv.feats, dim=1).double().numpy(), inside

    def to_work(self, M: np.ndarray, pts: np.ndarray) -> np.ndarray:
        return self.center + self.rho * apply(M, pts)

    def update_size(self, dp: np.ndarray) -> float:
        """How far an update moves template points (work px), taken at the template's extent."""
        if self.warp == "similarity":  # the paper's rule, kept as it was
            return self.rho * float(np.abs(dp).sum())
        return self.rho * float(np.abs(apply(update_matrix(dp, self.warp), _UNIT_BOX) - _UNIT_BOX).max())

    def align(self, feats: dict[str, torch.Tensor], origin: np.ndarray, crop_shape: tuple[int, int],
              M0: np.ndarray) -> AlignResult:
        """Refine the normalised warp M0 against feature maps of a crop with top-left at `origin`."""
        M = M0.copy()
        total = 0
        H_crop, W_crop = crop_shape
        lo = np.asarray(origin, float) + self.config.border
        hi = np.asarray(origin, float) + np.array([W_crop - 1, H_crop - 1]) - self.config.border
        valid_share, rms, per_level = 0.0, float("nan"), []
        for level, iters in zip(self.levels, self.config.iterations):
            fmap = feats[level.name][0] if feats[level.name].dim() == 4 else feats[level.name]
            for _ in range(iters):
                pts = self.to_work(M, level.pts)
                valid = (pts[:, 0] >= lo[0]) & (pts[:, 0] <= hi[0]) & (pts[:, 1] >= lo[1]) & (pts[:, 1] <= hi[1])
                valid_share = float(valid.mean())
                if valid.sum() < 6:
                    return AlignResult(M, total, valid_share, float("nan"), per_level)
                all_valid = bool(valid.all())
                sampled, _ = sample_points(fmap, pts if all_valid else pts[valid], origin, level.stride)
                err = sampled - (level.feats if all_valid else level.feats[valid])
                r = torch.linalg.vector_norm(err, dim=1).double().numpy()
                w = np.ones_like(r)
                if self.config.robust:
                    k = HUBER_K * max(MAD_TO_SIGMA * np.median(r), 1e-6)
                    w = np.where(r <= k, 1.0, k / np.maximum(r, 1e-12))
                C, P = err.shape[1], self.n_params
                sd = level.sd if all_valid else level.sd.view(-1, C, P)[torch.from_numpy(valid)].reshape(-1, P)
                b = ((err * torch.from_numpy(w).float()[:, None]).reshape(1, -1) @ sd)[0].double().numpy()
                H = (w @ (level.hess if all_valid else level.hess[valid])).reshape(P, P)
                try:
                    dp = np.linalg.solve(H, b)
                except np.linalg.LinAlgError:
                    return AlignResult(M, total, valid_share, float("nan"), per_level)
                M = M @ np.linalg.inv(update_matrix(dp, self.warp))
                if self.warp == "homography":
                    M = M / M[2, 2]
                total += 1
                rms = float(np.sqrt(np.mean(r ** 2)))
                if self.update_size(dp) < self.config.eps * level.stride:
                    break
            per_level.append((level.name, total))
        return AlignResult(M, total, valid_share, rms, per_level)
