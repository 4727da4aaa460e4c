"""Occlusion estimate OP_t (paper eq. 5–6): share of template pixels that differ by more than τ.

Grey as in the paper, or colour (a pixel differs when any channel does): a brown sleeve over a
red flag has nearly the red's grey level, and grey OP_t then reports a half-covered flag as clear.

Exposure-normalised (a change to the paper, `normalise_exposure`): the paper compares raw
intensities with τ = 30 grey levels, so an auto-exposure step of 25 % alone reads as occlusion of
every bright pixel. An exposure change multiplies the sensor's signal, and after the sRGB curve it
still (nearly) multiplies the encoded value, so the template is first scaled by one gain: the
median ratio patch / template over the pixels bright enough to carry it. The median holds while
less than half the patch is covered; past that the gain may follow the occluder, which can only
raise OP_t, never hide an occluder (and the gain is bounded to what an exposure change does in
one tracking gap, so a uniform dark coat is not explained away as an exposure drop).
"""

from __future__ import annotations

import cv2
import numpy as np

TAU_PIX = 30  # grey levels
GAIN_RANGE = (0.5, 2.0)  # exposure gains the normalisation may explain (outside: clipped, the rest is occlusion)
GAIN_MIN_LEVEL = 20  # template pixels darker than this carry too little signal to measure a gain ratio


def aligned_patch(grey: np.ndarray, A: np.ndarray, origin: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Warp the frame into template coordinates. A maps template → frame, origin = template's top-left.

    Returns the patch and a mask of pixels that came from inside the frame.
    """
    T = np.array([[1, 0, origin[0]], [0, 1, origin[1]], [0, 0, 1.0]])
    M = (A @ T)[:2]
    h, w = shape
    patch = cv2.warpAffine(grey, M, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT)
    inside = cv2.warpAffine(np.full(grey.shape[:2], 255, np.uint8), M, (w, h),
                            flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT) > 0
    return patch, inside


def exposure_gain(patch: np.ndarray, template: np.ndarray, inside: np.ndarray | None = None) -> float:
    """One gain g (patch ≈ g · template): the median ratio over visible, bright-enough pixels, within GAIN_RANGE."""
    t = template.astype(np.float32)
    p = patch.astype(np.float32)
    use = t > GAIN_MIN_LEVEL
    if inside is not None:
        use &= inside[..., None] if use.ndim == 3 else inside
    if use.sum() < 16:
        return 1.0
    return float(np.clip(np.median(p[use] / t[use]), *GAIN_RANGE))


def occlusion_fraction(patch: np.ndarray, template: np.ndarray, inside: np.ndarray | None = None,
                       tau: float = TAU_PIX, normalise_exposure: bool = False) -> float:
    """OP_t in [0, 1]; pixels that fall outside the frame count as occluded (not visible). With
    `normalise_exposure` the template is scaled by the exposure gain first (module docstring)."""
    if normalise_exposure:
        ref = template.astype(np.float32) * np.float32(exposure_gain(patch, template, inside))
        diff = np.abs(patch.astype(np.float32) - ref) > tau
    else:
        diff = np.abs(patch.astype(np.int16) - template.astype(np.int16)) > tau
    if diff.ndim == 3:  # colour
        diff = diff.any(axis=2)
    if inside is not None:
        diff |= ~inside
    return float(diff.mean())
