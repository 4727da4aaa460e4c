"""The homography's last refinement: inverse-compositional Gauss–Newton on the grey template, in its own frame.

The feature LK leaves a homography 0.1–0.3 px off (VGG features are not equivariant to perspective), so the
aligner refines it on the full-resolution grey template. OpenCV's ECC, which did this before, works in the frame's
pixels: it smooths the frame there and the template in the template's, and where the warp scales or shears the two are
smoothed by different amounts, which moved its optimum up to 0.3 px off the truth on sharp photos; and it costs
~0.25 ms an iteration on a 120×84 template (its Jacobian images are rebuilt every iteration).

Here every iteration resamples the frame onto the template's grid by the current warp (bicubic: bilinear
resampling smooths by the fraction of a pixel it lands on), smooths it there as the template was smoothed
(`ecc.prefilter`, the same Gaussian), fits the exposure (gain and offset, least squares: ECC's invariance) and
takes an inverse-compositional step (Baker & Matthews) whose steepest-descent images and Hessian come from the
template once (~0.1 ms a step). Deep LK with it instead of ECC, on perspective warps of four photos (scikit-learn's
and PyWavelets'; experiments/bench_homography.py), worst corner median / p90 / max: clean 0.064 / 0.41 / 0.82 →
0.042 / 0.13 / 0.15 px; with a 1.1× gain and noise 0.12 / 0.73 / 1.10 → 0.050 / 0.20 / 0.22 px.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.ecc import prefilter
from hvs_sim.tracking.feature_lk import warp_jacobian
from hvs_sim.tracking.warp import homography_params_to_matrix, inverse_3x3

IC_ITERATIONS = 15  # Gauss–Newton steps at most
IC_EPS_PX = 1e-3  # stop when a step moves the template's corners by less than this (full-resolution px)
IC_MAX_STEP_PX = 8.0  # a step that moves a corner further than this has diverged: no answer
# "template": the frame resampled bicubically and smoothed on the template's grid: the more accurate on warped
# photos (module docstring). "frame": smoothed in the frame's pixels, then resampled bilinearly, as ECC does; in the
# closed 6-DOF loop "template" ended further from the goal, which is not understood (docs/tuning.md,
# intensity_smooth). The hybrid uses "frame", deep_lk "template".
SMOOTH_MODES = ("template", "frame")
FRAME_MARGIN = 16  # px around the template's place in the frame smoothed for a call (smooth="frame")
MIN_PIXELS = 64  # fewer usable pixels than this: no answer
# grey levels at or beyond which a pixel is clipped (8-bit): it does not follow the exposure's gain and offset, so
# it and the pixels the Gaussian spreads it to are left out (warped photos under a 1.1× gain, 2–3 % of the
# template clipped, started ~1 px off: median worst corner 0.13 → 0.055 px on china, 0.41 → 0.18 px on ascent)
CLIP_LO, CLIP_HI = 1, 254


@dataclass
class ICResult:
    warp: np.ndarray  # (3, 3) template px → frame px, h33 = 1
    iterations: int
    converged: bool  # the last step was under IC_EPS_PX (else IC_ITERATIONS ran out)


class IntensityIC:
    """Homography alignment of a pre-filtered grey template (`ecc.ecc_template`) in a grey frame."""

    def __init__(self, template: np.ndarray, gauss: int, raw: np.ndarray | None = None, smooth: str = "template"):
        """`template`: pre-filtered (ecc.ecc_template); `raw`: the same pixels before the filter, to know which
        are clipped (None: none are taken as clipped). `smooth`: "template" resamples the frame bicubically
        and smooths it on the template's grid (module docstring); "frame" smooths the frame in its own pixels
        and resamples it bilinearly, as ECC does (see SMOOTH_MODES)."""
        if smooth not in SMOOTH_MODES:
            raise ConfigError(f"smooth must be one of {', '.join(SMOOTH_MODES)}, got {smooth!r}")
        self.smooth = smooth
        t = np.asarray(template, np.float32)
        h, w = t.shape
        self.template, self.gauss, self.shape = t, gauss, (h, w)
        self.pad = gauss // 2 + 2  # resampled beyond the template's edge so the Gaussian sees true neighbours there
        rho = max(w, h) / 2.0
        cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
        self.N = np.array([[1 / rho, 0, -cx / rho], [0, 1 / rho, -cy / rho], [0, 0, 1.0]])  # px → normalised
        self.N_inv = np.linalg.inv(self.N)
        ys, xs = np.mgrid[0:h, 0:w]
        pts = np.stack([(xs.ravel() - cx) / rho, (ys.ravel() - cy) / rho], 1)
        jx, jy = warp_jacobian(pts, "homography")
        gy, gx = np.gradient(t.astype(np.float64))
        # d T(N⁻¹ W(x̃; p)) / dp at p = 0: ∇T (px) · ρ · dx̃'/dp
        sd = rho * (gx.ravel()[:, None] * jx + gy.ravel()[:, None] * jy)  # (n, 8)
        self.sd_t = np.ascontiguousarray(sd.T, np.float32)  # (8, n): one matrix-vector product per step
        self.hess_inv = _inverse(sd.T @ sd)  # None: the template has too little texture to align
        self.t_flat = t.ravel()
        self.t0 = self.t_flat - float(self.t_flat.mean())
        self.sd_t0 = (self.sd_t @ self.t0).astype(np.float64)
        self.corners_h = np.array([[0, 0, 1], [w - 1, 0, 1], [w - 1, h - 1, 1], [0, h - 1, 1]], np.float64).T
        self.grid_h = np.stack([xs.ravel(), ys.ravel(), np.ones(h * w)]).astype(np.float64)  # for the frame check
        self.spread = np.ones((2 * (gauss // 2) + 1,) * 2, np.uint8)  # how far the Gaussian carries a pixel
        self.template_clipped = None if raw is None else self._clipped(np.asarray(raw))

    def _clipped(self, raw: np.ndarray) -> np.ndarray | None:
        """Flattened mask of the pixels a clipped raw pixel reaches through the Gaussian (None: no pixel is clipped)."""
        bad = (raw <= CLIP_LO) | (raw >= CLIP_HI)
        if not bad.any():
            return None
        return cv2.dilate(bad.astype(np.uint8), self.spread).ravel().astype(bool)

    def _frame_box(self, grey: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """smooth="frame": the frame smoothed over the box around the template's place under W (FRAME_MARGIN
        wider), and the shift from frame to box pixels."""
        c = W @ self.corners_h
        H, Wd = grey.shape[:2]
        if np.all(c[2] > 0):
            xy = c[:2] / c[2]
            x0, y0 = np.clip(np.floor(xy.min(1)) - FRAME_MARGIN, 0, [Wd - 1, H - 1]).astype(int)
            x1, y1 = np.clip(np.ceil(xy.max(1)) + FRAME_MARGIN + 1, [x0 + 1, y0 + 1], [Wd, H]).astype(int)
        else:
            x0, y0, x1, y1 = 0, 0, Wd, H
        shift = np.array([[1.0, 0, -x0], [0, 1.0, -y0], [0, 0, 1.0]])
        return prefilter(grey[y0:y1, x0:x1], self.gauss), shift

    def _resampled(self, grey: np.ndarray, W: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
        """The frame on the template's grid under W, smoothed as the template was (flattened float32); `box`:
        smooth="frame"'s smoothed box and its shift (`_frame_box`), else None."""
        h, w = self.shape
        if box is not None:
            smoothed, shift = box
            return cv2.warpPerspective(smoothed, shift @ W, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                       borderMode=cv2.BORDER_REPLICATE).ravel()
        p = self.pad
        to_frame = W @ np.array([[1.0, 0, -p], [0, 1.0, -p], [0, 0, 1.0]])
        patch = cv2.warpPerspective(grey, to_frame, (w + 2 * p, h + 2 * p), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                                    borderMode=cv2.BORDER_REPLICATE)
        return prefilter(patch, self.gauss)[p:p + h, p:p + w].ravel()

    def _in_frame(self, W: np.ndarray, frame_shape: tuple[int, int]) -> np.ndarray | None:
        """Template pixels that W puts inside the frame (None: all of them)."""
        H, Wd = frame_shape
        c = W @ self.corners_h
        if np.all(c[2] > 0):
            x, y = c[0] / c[2], c[1] / c[2]
            if x.min() >= 0 and y.min() >= 0 and x.max() <= Wd - 1 and y.max() <= H - 1:
                return None  # a convex quadrilateral inside the frame: every pixel is
        g = W @ self.grid_h
        with np.errstate(divide="ignore", invalid="ignore"):
            x, y = g[0] / g[2], g[1] / g[2]
        return (g[2] > 0) & (x >= 0) & (y >= 0) & (x <= Wd - 1) & (y <= H - 1)

    def align(self, grey: np.ndarray, W0: np.ndarray, seen: np.ndarray | None = None) -> ICResult | None:
        """Refine W0 (template px → frame px) in the grey frame; `seen`: template pixels to use (bool, template
        shape; None: all). None when too few pixels are usable, the system is singular or a step diverges."""
        if self.smooth == "template" or grey.dtype not in (np.uint8, np.float32):
            grey = grey.astype(np.float32, copy=False)  # bicubic resampling of uint8 would round its output
        W = np.asarray(W0, np.float64) / W0[2, 2]
        use = None if seen is None else np.asarray(seen, bool).ravel()
        inside = self._in_frame(W, grey.shape[:2])
        if inside is not None:
            use = inside if use is None else use & inside
        h, w = self.shape  # clipped pixels, in the frame where the start warp puts them and in the template
        raw = cv2.warpPerspective(grey, W, (w, h), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                                  borderMode=cv2.BORDER_REPLICATE)
        for clipped in (self._clipped(raw), self.template_clipped):
            if clipped is not None:
                use = ~clipped if use is None else use & ~clipped
        if use is None:  # the whole template: its system, made once
            sd_t, hess_inv, t0, sd_t0 = self.sd_t, self.hess_inv, self.t0, self.sd_t0
        else:
            if use.sum() < MIN_PIXELS:
                return None
            sd_t, t = np.ascontiguousarray(self.sd_t[:, use]), self.t_flat[use]
            hess_inv = _inverse(sd_t.astype(np.float64) @ sd_t.T.astype(np.float64))
            t0 = t - float(t.mean())
            sd_t0 = (sd_t @ t0).astype(np.float64)
        if hess_inv is None:
            return None
        box = self._frame_box(grey, W) if self.smooth == "frame" else None
        old = W @ self.corners_h
        old = old[:2] / old[2]
        for it in range(1, IC_ITERATIONS + 1):
            img = self._resampled(grey, W, box)
            if use is not None:
                img = img[use]
            # exposure: the frame's gain and offset that best match the template (least squares); the error
            # gain · (img − mean) − t0 enters only through sd_t, so sd_t @ t0 is taken once a call
            i0 = img - img.mean()
            var = float(i0 @ i0)
            if var <= 1e-9:
                return None
            dp = hess_inv @ ((float(i0 @ t0) / var) * (sd_t @ i0).astype(np.float64) - sd_t0)
            inv = inverse_3x3(homography_params_to_matrix(dp))
            if inv is None:
                return None
            W_new = W @ (self.N_inv @ inv @ self.N)
            W_new /= W_new[2, 2]
            new = W_new @ self.corners_h
            new = new[:2] / new[2]
            moved = float(np.abs(new - old).max())
            if not np.all(np.isfinite(W_new)) or not moved <= IC_MAX_STEP_PX:
                return None
            W, old = W_new, new
            if moved < IC_EPS_PX:
                return ICResult(W, it, True)
        return ICResult(W, IC_ITERATIONS, False)


def _inverse(hess: np.ndarray) -> np.ndarray | None:
    try:
        return np.linalg.inv(hess)
    except np.linalg.LinAlgError:
        return None
