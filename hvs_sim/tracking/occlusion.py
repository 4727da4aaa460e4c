"""Occlusion estimate OP_t (paper eq. 5–6): share of template pixels that differ by more than τ.

Grey as in the paper, or colour (a pixel differs when any channel does): a brown sleeve over a
red flag has nearly the red's grey level, and grey OP_t then reports a half-covered flag as clear.
"""

from __future__ import annotations

import cv2
import numpy as np

TAU_PIX = 30  # grey levels


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


def occlusion_fraction(patch: np.ndarray, template: np.ndarray, inside: np.ndarray | None = None,
                       tau: float = TAU_PIX) -> float:
    """OP_t in [0, 1]; pixels that fall outside the frame count as occluded (not visible)."""
    diff = np.abs(patch.astype(np.int16) - template.astype(np.int16)) > tau
    if diff.ndim == 3:  # colour
        diff = diff.any(axis=2)
    if inside is not None:
        diff |= ~inside
    return float(diff.mean())
