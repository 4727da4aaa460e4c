"""Point features as every law on them reads them: pixels normalised by K (x = (u − cx)/fx), their interaction
matrix, each point's depth from the target's apparent size, and the least-squares pieces on L (the damped
pseudo-inverse, its rank and condition). IBVS, PBVS (its reported image error and its pose error's weighting), the
loop's ControlInput, the photometric law's luminance rows (control/laws/dvs.py) and the budget's weak directions share
them, so that each is written once. Pure numpy.
"""

from __future__ import annotations

import numpy as np

from hvs_sim.errors import ConfigError, InputError

RANK_TOL = 1e-6  # singular values below this × the largest count as zero (rank of L)
MIN_DESIRED_SPREAD_PX = 1.0  # desired points closer together than this make L singular
INTERACTION_AT = ("current", "desired", "mean")  # where L is evaluated (IBVSConfig.interaction)
DEPTH_SOURCES = ("scale", "true")  # each point's depth: from the apparent size, or the simulator's (IBVSConfig.depth)


def normalise(px: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) as normalised image coordinates (x = (u − cx)/fx, y = (v − cy)/fy)."""
    return np.stack([(px[:, 0] - K[0, 2]) / K[0, 0], (px[:, 1] - K[1, 2]) / K[1, 1]], 1)


def point_rows(x: np.ndarray, y: np.ndarray, Z) -> tuple[np.ndarray, np.ndarray]:
    """(L_x, L_y), each (N, 6): the interaction rows of normalised points (x, y) at depths Z (a number or (N,))."""
    Z = np.broadcast_to(np.asarray(Z, float), np.shape(x))
    Lx = np.stack([-1 / Z, 0 * x, x / Z, x * y, -(1 + x * x), y], 1)
    Ly = np.stack([0 * x, -1 / Z, y / Z, 1 + y * y, -x * y, -x], 1)
    return Lx, Ly


def interaction_matrix(xy: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Stacked 2×6 interaction matrices of normalised points xy (N, 2) at depths Z (N,)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    Lx, Ly = point_rows(xy[:, 0], xy[:, 1], np.broadcast_to(np.asarray(Z, float), (len(xy),)))
    L = np.zeros((2 * len(xy), 6))
    L[0::2], L[1::2] = Lx, Ly
    return L


def rms_size(points: np.ndarray) -> float:
    """Size of a point set: RMS distance to its centroid (a similarity scale up to a constant)."""
    return float(np.sqrt(((points - points.mean(0)) ** 2).sum(1).mean()))


def scale_depths(s: np.ndarray, s_star: np.ndarray, desired_depth: float) -> np.ndarray:
    """Depth of every point from the apparent size: Z = Z* · size(s*) / size(s) (size: RMS distance to the centroid)."""
    return np.full(len(s), desired_depth * rms_size(s_star) / max(rms_size(s), 1e-9))


def damped_pinv(L: np.ndarray, mu: float) -> np.ndarray:
    """(LᵀL + μ²I)⁻¹Lᵀ through the SVD (L⁺ when μ = 0)."""
    if mu <= 0:
        return np.linalg.pinv(L)
    U, sv, Vt = np.linalg.svd(L, full_matrices=False)
    return (Vt.T * (sv / (sv ** 2 + mu ** 2))) @ U.T


def matrix_rank(sv: np.ndarray) -> int | None:
    """Rank from singular values (RANK_TOL relative to the largest); None when there are none."""
    return int((sv > RANK_TOL * sv.max()).sum()) if len(sv) and sv.max() > 0 else (0 if len(sv) else None)


def condition_number(sv: np.ndarray) -> float | None:
    """σ_max / σ_min; None when there are no singular values or the smallest is zero (rank-deficient)."""
    return float(sv.max() / sv.min()) if len(sv) and sv.min() > 0 else None


class PointFeatures:
    """s* and the camera's K, checked once: the current features' error to s*, their depths and L, as a law on the
    points reads them."""

    def __init__(self, K: np.ndarray, desired_px: np.ndarray, desired_depth: float):
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
        if not (np.isfinite(desired_depth) and desired_depth > 0):
            raise ConfigError(f"desired depth must be > 0 m, got {desired_depth}")
        self.desired_depth = float(desired_depth)
        self.s_star = normalise(self.desired_px, self.K)

    def error(self, features_px) -> tuple[np.ndarray, np.ndarray, float]:
        """(s, e = s − s* flattened, the mean corner distance to s* in pixels) of the current features (pixels)."""
        f = np.asarray(features_px, float).reshape(-1, 2)
        if f.shape != self.desired_px.shape or not np.isfinite(f).all():
            raise InputError(f"features must be finite pixels of shape {self.desired_px.shape}, got {f.shape}")
        s = normalise(f, self.K)
        return s, (s - self.s_star).reshape(-1), float(np.linalg.norm(f - self.desired_px, axis=1).mean())

    def depths(self, s: np.ndarray, given: np.ndarray | None, source: str) -> np.ndarray:
        """Each point's depth (m): the simulator's (`given`, source "true") or from the apparent size ("scale")."""
        if source == "true":
            if given is None or not np.all(np.asarray(given) > 0):
                raise InputError("depth='true' needs positive per-point depths from the simulator")
            return np.asarray(given, float)
        return scale_depths(s, self.s_star, self.desired_depth)

    def matrix(self, s: np.ndarray, Z: np.ndarray, at: str) -> np.ndarray:
        """L at the current features ("current"), at s* and Z* ("desired"), or the mean of the two ("mean")."""
        Zs = np.full(len(s), self.desired_depth)
        if at == "current":
            return interaction_matrix(s, Z)
        if at == "desired":
            return interaction_matrix(self.s_star, Zs)
        return 0.5 * (interaction_matrix(s, Z) + interaction_matrix(self.s_star, Zs))
