"""How well an image can be located by a template tracker: one measure that the scene's texture
sets (scene/textures/) and the trackers' init check (tracking/trackability.py) both use."""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np

TRACKABILITY_BLUR_SIGMA = 1.0
MAD_TO_SIGMA = 1.4826  # a Gaussian's std over its median absolute value


def _grey01(img: np.ndarray) -> np.ndarray:
    img = np.asarray(img)
    grey = img.astype(np.float32)
    if grey.ndim == 3:
        grey = cv2.cvtColor(grey, cv2.COLOR_RGB2GRAY)
    if img.dtype == np.uint8:
        grey /= 255.0
    return grey


def _tensor(grey: np.ndarray) -> tuple[float, float, float]:
    grey = cv2.GaussianBlur(grey, (0, 0), TRACKABILITY_BLUR_SIGMA)
    ix = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=1) * 0.5
    iy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=1) * 0.5
    return float(np.mean(ix * ix)), float(np.mean(ix * iy)), float(np.mean(iy * iy))


def _eigen(a: float, b: float, d: float) -> tuple[float, float]:
    r = math.sqrt(0.25 * (a - d) ** 2 + b * b)
    return 0.5 * (a + d) - r, 0.5 * (a + d) + r


@lru_cache(maxsize=1)
def _noise_gain() -> float:
    """Gradient energy (per axis) that white noise of unit variance leaves after trackability's blur and
    differences: the sum of the squared impulse response, computed from the same operations."""
    delta = np.zeros((33, 33), np.float32)
    delta[16, 16] = 1.0
    a, _, _ = _tensor(delta)
    return a * delta.size


def noise_sigma(grey: np.ndarray) -> float:
    """Additive noise (std, in the image's units) from Immerkær's 3×3 difference kernel (it cancels flat areas, ramps
    and straight edges away from their line), taken as the MEDIAN absolute response: thin lines and edges touch few
    pixels, so they do not pass for noise (Immerkær's mean would call a thin lattice against the sky noise)."""
    h, w = grey.shape
    if h < 3 or w < 3:
        return 0.0
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)  # response std 6σ for white noise σ
    response = cv2.filter2D(grey.astype(np.float32), -1, kernel)[1:-1, 1:-1]
    return float(MAD_TO_SIGMA * np.median(np.abs(response)) / 6.0)


def structure(img: np.ndarray) -> tuple[float, float]:
    """(smallest, largest) eigenvalue of the mean structure tensor (as `trackability`) with the sensor noise's share
    taken out (noise_sigma): what the image's content gives in its weakest and strongest direction. Noise alone
    raises both equally, so that a plain sky or a single edge seen through a noisy sensor does not pass for
    texture."""
    grey = _grey01(img)
    floor = _noise_gain() * noise_sigma(grey) ** 2
    lo, hi = _eigen(*_tensor(grey))
    return max(lo - floor, 0.0), max(hi - floor, 0.0)


def trackability(img: np.ndarray) -> float:
    """Smallest eigenvalue of the image's mean structure tensor: how well a template of the whole
    image can be located in both directions (Shi-Tomasi / KLT criterion, image-wide).

    The image (RGB or grey, uint8 or float in [0, 1]) is turned grey in [0, 1], blurred with a
    Gaussian of sigma 1 px, and Ix, Iy are central differences in intensity per pixel; the value is
    the min eigenvalue of mean([[Ix², IxIy], [IxIy, Iy²]]). A flat image scores 0, and so does a
    single edge or stripe direction (aperture problem: it can slide along the stripes). One global
    tensor rather than a percentile of patches, because a target is tracked as a whole: a poster's
    flat margins do not make it untrackable. Values fall as the image is scaled up (gradients per
    pixel shrink): measure at the resolution the tracker sees. At 256 px, as a rule of thumb:
    < 1e-4 poor (flat, clear sky, wood grain, fine sand), 1e-4 to 5e-4 fair (marble, dark fur, some
    posters), > 5e-4 good (brick, gravel, foliage, fabric, cork board, photos).
    """
    return _eigen(*_tensor(_grey01(img)))[0]
