"""The Cramér–Rao bound on the camera's 6-DOF pose from the pixels of a planar target: the accuracy limit of any
unbiased estimator (tracker + servo law) that reads those pixels with that camera's noise.

With image noise of variance σ²_i at pixel i (independent pixels), the Fisher information of a small camera
displacement δ (vx, vy, vz in m; wx, wy, wz in rad) is F = Σ_i L_iᵀ L_i / σ²_i, L_i the luminance interaction row
of the pixel (control/laws/dvs.py: the intensity gradient times the point interaction matrix at the target's depth),
and cov(δ̂) ≥ F⁻¹. Averaging n independent frames divides it by n.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hvs_sim.control.laws.dvs import luminance_interaction
from hvs_sim.control.protocol import DOF_NAMES
from hvs_sim.errors import InputError


@dataclass(frozen=True)
class PoseBound:
    cov: np.ndarray  # (k, k) the bound on the covariance of the pose DOFs `dofs` (m², rad²)
    dofs: tuple[str, ...]
    pixels: int  # pixels that carried information

    def scaled(self, frames: float) -> PoseBound:
        """The bound for `frames` independent frames averaged."""
        return PoseBound(self.cov / frames, self.dofs, self.pixels)

    @property
    def translation_mm(self) -> float:
        """1-σ of the translation (root of the trace of its covariance), mm."""
        idx = [i for i, d in enumerate(self.dofs) if d.startswith("v")]
        return 1e3 * float(np.sqrt(np.trace(self.cov[np.ix_(idx, idx)]))) if idx else 0.0

    @property
    def rotation_deg(self) -> float:
        idx = [i for i, d in enumerate(self.dofs) if d.startswith("w")]
        return float(np.degrees(np.sqrt(np.trace(self.cov[np.ix_(idx, idx)])))) if idx else 0.0

    def per_dof(self) -> dict[str, float]:
        """1-σ of each DOF: mm for translations, degrees for rotations."""
        sd = np.sqrt(np.diag(self.cov))
        return {d: float(1e3 * s if d.startswith("v") else np.degrees(s)) for d, s in zip(self.dofs, sd, strict=True)}


def pose_bound(grad_x: np.ndarray, grad_y: np.ndarray, x: np.ndarray, y: np.ndarray, depth, variance: np.ndarray,
               dofs: tuple[str, ...] = DOF_NAMES) -> PoseBound:
    """The bound from per-pixel intensity gradients in normalised coordinates (intensity per unit of x = (u − cx)/fx),
    the pixels' normalised coordinates, depths (m) and noise variances (same intensity units²; inf: no information)."""
    g = [np.asarray(a, float).ravel() for a in (grad_x, grad_y, x, y, variance)]
    if len({a.size for a in g}) != 1 or not g[0].size:
        raise InputError("gradients, coordinates and variances must be arrays of one non-zero size")
    gx, gy, x, y, var = g
    use = np.isfinite(var) & (var > 0) & np.isfinite(gx) & np.isfinite(gy)
    cols = [DOF_NAMES.index(d) for d in dofs]
    L = luminance_interaction(gx[use], gy[use], x[use], y[use], np.broadcast_to(np.asarray(depth, float),
                                                                              gx.shape)[use])[:, cols]
    F = (L / var[use, None]).T @ L
    if np.linalg.matrix_rank(F) < len(cols):
        raise InputError(f"the pixels carry no information on some of {', '.join(dofs)} (flat or one-directional "
                         "texture): the bound is infinite")
    return PoseBound(np.linalg.inv(F), tuple(dofs), int(use.sum()))
