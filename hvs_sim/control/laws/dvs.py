"""Photometric visual servoing (DVS, direct visual servoing): the luminance of the target's pixels is the feature.

Collewet & Marchand (2011), as ViSP's `vpFeatureLuminance`: with brightness constancy, a pixel's intensity changes
as dI/dt = −∇I · ẋ, so the interaction matrix of the luminance at normalised point (x, y) of depth Z is

    L_I = −(I_x L_x + I_y L_y),

L_x, L_y the rows of the point interaction matrix and (I_x, I_y) the image gradient in normalised coordinates
(pixel gradient × focal length). The error is e = I − I* over the goal image's target region; the law is
Levenberg–Marquardt, v = −λ (H + μ diag(H))⁻¹ L_Iᵀ e with H = L_Iᵀ L_I, L_I taken at the goal (the target's plane
faces the camera at depth Z* there) and so computed once.

It needs no tracker while the target is visible and is blind under occlusion: an occluder's pixels are error like
any other. Its basin of convergence is small (the pixels must still overlap their goal appearance).
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.control.features import point_rows
from hvs_sim.control.laws.ibvs import DOF_NAMES, ControlOutput, IBVSConfig, bound_twist
from hvs_sim.control.protocol import ControlInput
from hvs_sim.errors import InputError

DVS_STRIDE = 2  # every 2nd pixel of the target region in each direction: a quarter of the rows, the same basin
# Levenberg–Marquardt's μ: H + μ diag(H); Collewet & Marchand's value, which damps the first steps from far away
DVS_MU = 0.01
DVS_BLUR_SIGMA = 1.0  # px: the goal image smoothed before its gradients, the current frame alike (noise, aliasing)


def luminance_interaction(Ix: np.ndarray, Iy: np.ndarray, x: np.ndarray, y: np.ndarray, Z) -> np.ndarray:
    """(N, 6) interaction matrix of the luminance at normalised points (x, y) of depth Z, gradients (Ix, Iy) in
    intensity per unit of normalised coordinate."""
    Lx, Ly = point_rows(x, y, Z)
    return -(Ix[:, None] * Lx + Iy[:, None] * Ly)


def gradients(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(∂I/∂u, ∂I/∂v) of a grey float image in intensity per pixel (3×3 Sobel, normalised)."""
    return (cv2.Sobel(image, cv2.CV_64F, 1, 0, ksize=3) / 8.0, cv2.Sobel(image, cv2.CV_64F, 0, 1, ksize=3) / 8.0)


def grey(image: np.ndarray) -> np.ndarray:
    """An RGB uint8 (or grey) image as smoothed float intensities in [0, 255]."""
    img = np.asarray(image)
    g = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img
    return cv2.GaussianBlur(g.astype(np.float32), (0, 0), DVS_BLUR_SIGMA).astype(np.float64)


class DVSController:
    """Photometric servoing to the goal image's target region (x, y, w, h pixels), given intrinsics K."""

    uses_features = False

    def __init__(self, K: np.ndarray, goal_image: np.ndarray, roi, desired_depth: float,
                 config: IBVSConfig | None = None):
        self.config = config or IBVSConfig()
        self.K = np.asarray(K, float)
        if goal_image is None or np.asarray(goal_image).ndim not in (2, 3):
            raise InputError("DVS needs the goal image (H×W or H×W×3)")
        if not (np.isfinite(desired_depth) and desired_depth > 0):
            raise InputError(f"desired depth must be > 0 m, got {desired_depth}")
        x0, y0, w, h = (int(v) for v in roi)
        g = grey(goal_image)
        if w < 2 * DVS_STRIDE or h < 2 * DVS_STRIDE or x0 < 0 or y0 < 0 or x0 + w > g.shape[1] or y0 + h > g.shape[0]:
            raise InputError(f"DVS region {tuple(roi)} must lie inside the {g.shape[1]}×{g.shape[0]} goal image")
        v, u = np.mgrid[y0:y0 + h:DVS_STRIDE, x0:x0 + w:DVS_STRIDE]
        self.u, self.v = u.ravel(), v.ravel()
        gx, gy = gradients(g)
        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        x, y = (self.u - cx) / fx, (self.v - cy) / fy
        self.I_star = g[self.v, self.u]
        self.dofs = tuple(self.config.dofs or DOF_NAMES)  # IBVSConfig.dofs: the DOFs commanded (the rest stay 0)
        self.cols = [DOF_NAMES.index(d) for d in self.dofs]
        self.L = luminance_interaction(gx[self.v, self.u] * fx, gy[self.v, self.u] * fy, x, y,
                                       desired_depth)[:, self.cols]
        H = self.L.T @ self.L
        if np.linalg.matrix_rank(H) < len(H):
            raise InputError("DVS: the goal image's target region has too little texture (flat, or changing in one "
                             "direction only) for its luminance to say how the camera moves")
        self._solve = np.linalg.inv(H + DVS_MU * np.diag(np.diag(H))) @ self.L.T  # (6, N): L and μ are fixed
        self.singular_values = np.linalg.svd(self.L, compute_uv=False)

    def error(self, image: np.ndarray) -> np.ndarray:
        """I − I* over the region's pixels."""
        g = grey(image)
        if g.shape[0] <= self.v.max() or g.shape[1] <= self.u.max():
            raise InputError(f"DVS: frame of {g.shape[1]}×{g.shape[0]} is smaller than the goal image's region")
        return g[self.v, self.u] - self.I_star

    def compute(self, inp: ControlInput) -> ControlOutput:
        """The twist for the current frame (inp.image); the features and mode are not read."""
        if inp.image is None:
            raise InputError("DVS reads the current frame: the ControlInput has no image")
        e = self.error(inp.image)
        lam = self.config.gain
        twist = np.zeros(6)
        twist[self.cols] = -lam * (self._solve @ e)
        twist, saturated = bound_twist(twist, self.config.max_linear, self.config.max_angular)
        # error_px: no corners here; the RMS intensity error stands in the error vector
        return ControlOutput(twist, e, 0.0, lam, saturated, self.singular_values, self.dofs)
