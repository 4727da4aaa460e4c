"""Occlusion estimate OP_t (paper eq. 5–6): share of template pixels that differ by more than τ.

Grey as in the paper, or colour (a pixel differs when any channel does): a brown sleeve over a
red flag has nearly the red's grey level, and grey OP_t then reports a half-covered flag as clear.

Exposure-normalised (a change to the paper, `normalise_exposure`): the paper compares raw
intensities with τ = 30 grey levels, so an auto-exposure step of 25 % alone reads as occlusion of
every bright pixel. An exposure change multiplies the sensor's signal, and after the sRGB curve it
still (nearly) multiplies the encoded value, so the template is first scaled by one gain g: the mode
of the per-pixel log ratios patch / template. The visible part of a target shares one ratio while
an occluder's ratios spread (its values have nothing to do with the template's), so the mode finds
the exposure even when less than half the target shows. When fewer than half the pixels agree with
g, the gain cannot be told from a cover and OP_t is the larger of the normalised and raw values:
the normalisation only ever lowers OP_t where it clearly explains the change.
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.tracking.warp import warp_image

TAU_PIX = 30  # grey levels
GAIN_RANGE = (0.5, 2.0)  # exposure gains the normalisation may explain
GAIN_MIN_LEVEL = 20  # template pixels darker than this carry too little signal to measure a gain ratio
GAIN_BIN = 0.04  # log-ratio histogram bin (4 % in gain)
MIN_SUPPORT = 0.5  # share of pixels that must agree with the gain for it to be trusted
_LOG_LO, _LOG_HI = np.log(GAIN_RANGE)
_N_BINS = max(1, int(np.ceil((_LOG_HI - _LOG_LO) / GAIN_BIN)))
_EDGES = np.linspace(_LOG_LO, _LOG_HI, _N_BINS + 1)  # the edges np.histogram(bins=_N_BINS, range=…) uses


def _log_ratio_counts(r: np.ndarray) -> np.ndarray:
    """np.histogram(r, bins=_N_BINS, range=(_LOG_LO, _LOG_HI))[0] for r inside that range, without its
    generic-path overhead (a third of exposure_gain's time): a first guess of each bin, then the same
    correction against the edges that np.histogram makes, so every count is the same."""
    x = r.astype(np.float64)
    idx = ((x - _LOG_LO) * (_N_BINS / (_LOG_HI - _LOG_LO))).astype(np.intp)
    np.clip(idx, 0, _N_BINS - 1, out=idx)
    idx -= x < _EDGES[idx]
    idx += (x >= _EDGES[idx + 1]) & (idx != _N_BINS - 1)
    return np.bincount(idx, minlength=_N_BINS)


def aligned_patch(grey: np.ndarray, A: np.ndarray, origin: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Warp the frame into template coordinates. A maps template → frame, origin = template's top-left.

    Returns the patch and a mask of pixels that came from inside the frame.
    """
    T = np.array([[1, 0, origin[0]], [0, 1, origin[1]], [0, 0, 1.0]])
    M = A @ T
    h, w = shape
    patch = warp_image(grey, M, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT)
    if _all_inside(M, (h, w), grey.shape[:2]):  # the common case, without warping a frame-sized mask
        return patch, np.ones((h, w), bool)
    inside = warp_image(np.full(grey.shape[:2], 255, np.uint8), M, (w, h),
                        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT) > 0
    return patch, inside


def _all_inside(M: np.ndarray, shape: tuple[int, int], frame_shape: tuple[int, int]) -> bool:
    """Whether every pixel centre of a (h, w) patch lands inside the frame under M: its four corner
    centres do (the patch is convex, and so is its image under an affine map or a homography that
    keeps all four in front)."""
    h, w = shape
    corners = np.array([[0.0, 0.0, 1.0], [w - 1.0, 0.0, 1.0], [w - 1.0, h - 1.0, 1.0], [0.0, h - 1.0, 1.0]]) @ M.T
    if np.any(corners[:, 2] <= 0):
        return False
    x, y = corners[:, 0] / corners[:, 2], corners[:, 1] / corners[:, 2]
    H, W = frame_shape
    return bool(x.min() >= 0 and y.min() >= 0 and x.max() <= W - 1 and y.max() <= H - 1)


def exposure_gain(patch: np.ndarray, template: np.ndarray, inside: np.ndarray | None = None) -> float:
    """One gain g (patch ≈ g · template): the mode of the log ratios over visible, bright-enough
    pixels (module docstring), within GAIN_RANGE; 1 when too few pixels carry a ratio."""
    t = template.astype(np.float32)
    p = patch.astype(np.float32)
    use = t > GAIN_MIN_LEVEL
    if inside is not None:
        use &= inside[..., None] if use.ndim == 3 else inside
    if np.count_nonzero(use) < 16:
        return 1.0
    r = np.log(np.maximum(p[use], 0.5) / t[use])
    r = r[(r >= _LOG_LO) & (r <= _LOG_HI)]
    if r.size < 16:
        return 1.0
    hist = np.convolve(_log_ratio_counts(r), np.ones(3), mode="same")  # a ratio on a bin edge counts for both sides
    k = int(np.argmax(hist))
    near = r[np.abs(r - 0.5 * (_EDGES[k] + _EDGES[k + 1])) <= 1.5 * GAIN_BIN]
    return float(np.exp(np.median(near))) if near.size else 1.0


def _differs(patch: np.ndarray, ref: np.ndarray, tau: float, inside: np.ndarray | None) -> float:
    diff = np.abs(patch.astype(np.float32) - ref) > tau
    if diff.ndim == 3:  # colour
        diff = diff.any(axis=2)
    if inside is not None:
        diff |= ~inside
    return float(diff.mean())


def occlusion_fraction(patch: np.ndarray, template: np.ndarray, inside: np.ndarray | None = None,
                       tau: float = TAU_PIX, normalise_exposure: bool = False) -> float:
    """OP_t in [0, 1]; pixels that fall outside the frame count as occluded (not visible). With
    `normalise_exposure` the template is scaled by the exposure gain first (module docstring)."""
    raw = _differs(patch, template.astype(np.float32), tau, inside)
    if not normalise_exposure:
        return raw
    gain = exposure_gain(patch, template, inside)
    op = _differs(patch, template.astype(np.float32) * np.float32(gain), tau, inside)
    return op if 1.0 - op >= MIN_SUPPORT else max(op, raw)
