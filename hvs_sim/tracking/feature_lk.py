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

Speed: the Gauss–Newton loop runs in numpy on channels-last feature maps (`bilinear_rows`), not in
torch. Its arrays are small (≤ 2k points × 64 channels), where torch's per-call overhead and its
two-thread parallel regions cost more than the arithmetic (and far more when another process holds
a core). The right-hand side b = Σ w SDᵀ e is taken as Jxᵀ(w·⟨ρ∇xF, e⟩) + Jyᵀ(w·⟨ρ∇yF, e⟩): two
dot products per point instead of a (N·C × P) product, the same sum regrouped. The levels before
the last stop at a looser threshold (LKConfig.coarse_eps): only the last level's optimum is the answer.
With `LKConfig.channels` = k the loop runs on the features projected on the k directions that carry
most of the template's feature-gradient energy (`gradient_basis`): the gather, the residuals and the
products shrink by k/C, and the directions dropped are those along which a misalignment barely
changes the features (the hybrid: 8 of 64; README, tracker speed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.nets.vgg import STRIDES
from hvs_sim.tracking.occlusion import median_1d
from hvs_sim.tracking.warp import (
    WARP_PARAMS,
    apply,
    check_warp,
    homography_params_to_matrix,
    inverse_3x3,
    is_affine,
    params_to_matrix,
)
from hvs_sim.validate import check_number

HUBER_K = 1.345  # Huber threshold in robust standard deviations (95 % efficiency on Gaussian residuals)
MAD_TO_SIGMA = 1.4826  # median absolute deviation → standard deviation
_UNIT_CORNERS = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))  # normalised template extent
PREDICT_MAX_RATIO = 0.5  # LKConfig.predict_stop trusts a geometric tail only when updates at least halve


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
    # stopping rule of the levels before the last (× stride, as eps; None: eps, as the paper). Each
    # coarser level lands 0.1–0.3 px from the next one's optimum, so converging it to eps buys nothing
    # downstream: at 1e-2 the final warp moved by < 1e-3 px (median < 1e-4) on hand-held walk_by
    # while pool2 and pool1 took 2.4 (homography 4) iterations fewer per frame
    coarse_eps: float | None = 1e-2
    # also stop a level when the updates shrink geometrically (ratio q ≤ PREDICT_MAX_RATIO) and the
    # movement still to come, d·q / (1 − q) for an update d, is below the level's threshold
    predict_stop: bool = False
    # project each level's features on this many directions before the Gauss–Newton loop (None: all
    # channels). The directions are the template's principal feature-gradient directions
    # (`gradient_basis`), so the projection keeps what moves the alignment and drops what does not
    channels: int | None = None

    def __post_init__(self):
        bad = [lv for lv in self.levels if lv not in STRIDES]
        if bad or not self.levels:
            raise ConfigError(f"LK levels {self.levels} invalid; accepted: a sequence of {', '.join(STRIDES)}")
        if len(self.iterations) != len(self.levels) or min(self.iterations) < 1:
            raise ConfigError("LK iterations must give one positive count per level")
        if not self.eps > 0 or (self.coarse_eps is not None and not self.coarse_eps > 0):
            raise ConfigError(f"LK eps and coarse_eps must be > 0, got {self.eps}, {self.coarse_eps}")
        if self.channels is not None:
            check_number("LK channels (None: all)", self.channels, 1, integer=True)

    def threshold(self, level: int, stride: int) -> float:
        """Work px below which an update ends level number `level` (of stride `stride`)."""
        coarse = level < len(self.levels) - 1 and self.coarse_eps is not None
        return (self.coarse_eps if coarse else self.eps) * stride


def bilinear_rows(fmap: np.ndarray, ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
    """Bilinear samples (N, C) float32 of a channels-last map `fmap` (H, W, C) at feature-grid points
    (ux, uy): what `sample_points` (grid_sample, border padding, align_corners) gives, in numpy with
    one gather of the four neighbours (no torch call per LK iteration)."""
    H, W, C = fmap.shape
    x = np.clip(ux, 0.0, W - 1.0)
    y = np.clip(uy, 0.0, H - 1.0)
    x0, y0 = x.astype(np.intp), y.astype(np.intp)  # floor: x, y ≥ 0
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    fx, fy = (x - x0).astype(np.float32), (y - y0).astype(np.float32)
    y0 *= W
    y1 *= W
    idx = np.concatenate([y0 + x0, y0 + x1, y1 + x0, y1 + x1])
    corners = np.take(fmap.reshape(H * W, C), idx, axis=0).reshape(4, -1, C)
    gx, gy = 1.0 - fx, 1.0 - fy
    weights = np.stack([gx * gy, fx * gy, gx * fy, fx * fy])
    return np.einsum("kn,knc->nc", weights, corners)


def gradient_basis(gx: np.ndarray, gy: np.ndarray, k: int) -> np.ndarray | None:
    """(C, k) orthonormal float32 directions of feature space that carry most of the template's
    feature-gradient energy (the top right singular vectors of [∇xF; ∇yF]), or None when k does not
    reduce C. Projecting template and image features on them keeps the Gauss–Newton Hessian's
    largest part: an LK in a k-channel subspace that costs k/C of the full one per iteration."""
    C = gx.shape[1]
    if k >= C:
        return None
    G = np.concatenate([gx, gy]).astype(np.float64)
    _, _, vt = np.linalg.svd(G, full_matrices=False)
    return np.ascontiguousarray(vt[:k].T, dtype=np.float32)


def _inverse_update(dp: np.ndarray, warp: str) -> np.ndarray | None:
    """W(Δp)⁻¹: closed form for the similarity [[c, −b, tx], [b, c, ty]] (c = 1 + a), else the 3×3 adjugate
    (None: W(Δp) is singular)."""
    if warp != "similarity":
        return inverse_3x3(update_matrix(dp, warp))
    a, b, tx, ty = dp
    c = 1.0 + a
    d = c * c + b * b
    ci, bi = c / d, b / d  # R⁻¹ = [[ci, bi], [−bi, ci]]
    return np.array([[ci, bi, -(ci * tx + bi * ty)], [-bi, ci, bi * tx - ci * ty], [0.0, 0.0, 1.0]])


def channels_last(fmap: torch.Tensor) -> np.ndarray:
    """A (C, H, W) or (1, C, H, W) feature map as a contiguous (H, W, C) float32 numpy array (no copy
    when the tensor is already channels-last in memory, as Aligner.features returns it)."""
    f = fmap[0] if fmap.dim() == 4 else fmap
    return np.ascontiguousarray(f.permute(1, 2, 0).numpy(), dtype=np.float32)


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
    # numpy copies for the Gauss–Newton loop: template features and ρ-scaled feature gradients (N, C)
    # float32; transposed (·, N) float64: the points [x; y; 1], the warp Jacobians (P, N) with
    # sd = gx ⊗ jx + gy ⊗ jy, and the Hessians (P², N)
    feats_np: np.ndarray = None
    gx: np.ndarray = None
    gy: np.ndarray = None
    pts_h: np.ndarray = None
    jx: np.ndarray = None
    jy: np.ndarray = None
    hess_t: np.ndarray = None
    basis: np.ndarray | None = None  # (C, k) projection of the numpy loop's features (LKConfig.channels)
    basis_rows: torch.Tensor | None = None  # the same as a contiguous (k, C) tensor, for F.linear

    def __post_init__(self):
        if self.basis is not None:
            self.basis_rows = torch.from_numpy(np.ascontiguousarray(self.basis.T))


@dataclass
class AlignResult:
    M: np.ndarray  # final warp in normalised coordinates
    iterations: int
    valid: float  # share of template points that landed inside the image crop (last level)
    residual: float  # RMS feature residual of the valid points (last level; in its k-channel subspace with LKConfig.channels)
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
            jx_np, jy_np = warp_jacobian(pts, self.warp)
            jx, jy = torch.from_numpy(jx_np).float(), torch.from_numpy(jy_np).float()
            gx_r, gy_r = (gx * self.rho).contiguous(), (gy * self.rho).contiguous()
            sd = gx_r[:, :, None] * jx[:, None, :] + gy_r[:, :, None] * jy[:, None, :]
            P = self.n_params
            hess = torch.einsum("nci,ncj->nij", sd, sd).double().numpy().reshape(-1, P * P)
            pts_h = np.ascontiguousarray(np.c_[pts, np.ones(len(pts))].T)
            f_np, gx_np, gy_np, hess_np = f.numpy(), gx_r.numpy(), gy_r.numpy(), hess
            basis = None if self.config.channels is None else gradient_basis(gx_np, gy_np, self.config.channels)
            if basis is not None:  # the loop's copies in the subspace, and their Hessians
                f_np, gx_np, gy_np = f_np @ basis, gx_np @ basis, gy_np @ basis
                sd_k = gx_np[:, :, None] * jx_np[:, None, :] + gy_np[:, :, None] * jy_np[:, None, :]
                hess_np = np.einsum("nci,ncj->nij", sd_k, sd_k).reshape(-1, P * P).astype(np.float64)
            self.levels.append(_Level(name, s, pts, f, sd.reshape(-1, P).contiguous(), hess, grid,
                                      np.ascontiguousarray(f_np), np.ascontiguousarray(gx_np),
                                      np.ascontiguousarray(gy_np), pts_h, np.ascontiguousarray(jx_np.T),
                                      np.ascontiguousarray(jy_np.T), np.ascontiguousarray(hess_np.T), basis))

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
        (a, b, c), (d, e, f), (g, h, i) = update_matrix(dp, self.warp).tolist()  # the unit box's corners, in floats
        size = 0.0
        for x, y in _UNIT_CORNERS:
            w = g * x + h * y + i
            if w == 0.0:  # a corner sent to infinity: an update of no finite size
                return math.inf
            size = max(size, abs((a * x + b * y + c) / w - x), abs((d * x + e * y + f) / w - y))
        return self.rho * size

    def align(self, feats: dict[str, torch.Tensor], origin: np.ndarray, crop_shape: tuple[int, int],
              M0: np.ndarray) -> AlignResult:
        """Refine the normalised warp M0 against feature maps of a crop with top-left at `origin`."""
        M = M0.copy()
        total = 0
        H_crop, W_crop = crop_shape
        lo = np.asarray(origin, float) + self.config.border
        hi = np.asarray(origin, float) + np.array([W_crop - 1, H_crop - 1]) - self.config.border
        valid_share, rms, per_level = 0.0, float("nan"), []
        r_last = None
        P = self.n_params
        for li, (level, iters) in enumerate(zip(self.levels, self.config.iterations)):
            stop = self.config.threshold(li, level.stride)
            last_size = None
            fmap = channels_last(feats[level.name])
            if level.basis is not None:
                # torch, not numpy: numpy's matmul would wake BLAS's own thread pool beside torch's (4.5 ms
                # against 0.1); F.linear, not @: a third less time on these shapes
                flat = F.linear(torch.from_numpy(fmap.reshape(-1, fmap.shape[2])), level.basis_rows)
                fmap = flat.numpy().reshape(*fmap.shape[:2], -1)  # (H, W, k)
            # work px → this level's feature grid: u = (x − shift) / σ; the crop's usable box in u
            shift = np.asarray(origin, float) + (level.stride - 1) / 2.0
            (ux_lo, uy_lo), (ux_hi, uy_hi) = (lo - shift) / level.stride, (hi - shift) / level.stride
            to_grid = np.diag([self.rho / level.stride, self.rho / level.stride, 1.0])
            to_grid[:2, 2] = (self.center - shift) / level.stride  # normalised → feature grid
            n_all = level.pts_h.shape[1]
            for _ in range(iters):
                G = to_grid @ M
                U = G[:2] @ level.pts_h  # (2, N) grid coordinates of the warped points
                if not is_affine(G):
                    U /= G[2] @ level.pts_h
                ux, uy = U
                if ux.min() >= ux_lo and ux.max() <= ux_hi and uy.min() >= uy_lo and uy.max() <= uy_hi:
                    n_valid = n_all
                    T, gx, gy, jx, jy, hess = (level.feats_np, level.gx, level.gy, level.jx, level.jy,
                                               level.hess_t)
                else:
                    valid = (ux >= ux_lo) & (ux <= ux_hi) & (uy >= uy_lo) & (uy <= uy_hi)
                    n_valid = int(np.count_nonzero(valid))
                    if n_valid < 6:
                        return AlignResult(M, total, n_valid / n_all, float("nan"), per_level)
                    T, gx, gy = level.feats_np[valid], level.gx[valid], level.gy[valid]
                    jx, jy, hess = level.jx[:, valid], level.jy[:, valid], level.hess_t[:, valid]
                    ux, uy = ux[valid], uy[valid]
                valid_share = n_valid / n_all
                err = bilinear_rows(fmap, ux, uy)
                err -= T
                r = np.sqrt(np.einsum("nc,nc->n", err, err), dtype=np.float64)
                if self.config.robust:
                    k = HUBER_K * max(MAD_TO_SIGMA * median_1d(r), 1e-6)
                    w = np.minimum(k / np.maximum(r, 1e-12), 1.0)  # Huber: 1 for r ≤ k, k / r beyond
                else:
                    w = np.ones_like(r)
                # b = Σ_n w_n SD_nᵀ e_n with SD_n = ρ∇xF_n ⊗ jx_n + ρ∇yF_n ⊗ jy_n (module docstring)
                ex = np.einsum("nc,nc->n", gx, err).astype(np.float64)
                ey = np.einsum("nc,nc->n", gy, err).astype(np.float64)
                ex *= w
                ey *= w
                # einsum, not @: its loops stay on this thread (BLAS would wake its pool for P·N ≳ 10k)
                b = np.einsum("pn,n->p", jx, ex) + np.einsum("pn,n->p", jy, ey)
                H = np.einsum("qn,n->q", hess, w).reshape(P, P)
                try:
                    dp = np.linalg.solve(H, b)
                except np.linalg.LinAlgError:
                    return AlignResult(M, total, valid_share, float("nan"), per_level)
                inv = _inverse_update(dp, self.warp)
                if inv is None:
                    return AlignResult(M, total, valid_share, float("nan"), per_level)
                M = M @ inv
                if self.warp == "homography":
                    M = M / M[2, 2]
                total += 1
                r_last = r
                size = self.update_size(dp)
                if size < stop:
                    break
                if self.config.predict_stop and last_size is not None and size <= PREDICT_MAX_RATIO * last_size:
                    q = size / last_size
                    if size * q / (1.0 - q) < stop:
                        break
                last_size = size
            per_level.append((level.name, total))
        if r_last is not None:
            rms = float(np.sqrt(np.mean(r_last ** 2)))
        return AlignResult(M, total, valid_share, rms, per_level)
