"""OpenCV's ECC with the Gaussian pre-filter applied before the template is cut out.

`cv2.findTransformECC(template, image, …, gaussFiltSize)` smooths the template and the image
separately. The template is a crop, so its outer two pixels are smoothed against a reflected border
while the same pixels in the image are smoothed against their true neighbours: where a strong edge
runs near the crop's border (a flag's outline against the board behind it) the two disagree, and
ECC moves the warp to split the difference. On a clean render of the servo target, ECC started from
the true homography, or from the template's own place on the very frame it came from, ended 0.01–0.25 px
from it at the template's corners. Smoothing the whole frame first and cutting the template from it,
then letting ECC smooth nothing (size 1), removes that: the same start stays at the truth.
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.errors import ConfigError


def check_gauss(gauss: int, name: str = "gauss") -> int:
    """OpenCV's Gaussian pre-filter needs an odd size (an even one fails on every frame)."""
    if isinstance(gauss, bool) or not isinstance(gauss, (int, np.integer)) or gauss < 1 or gauss % 2 == 0:
        raise ConfigError(f"{name} (ECC's Gaussian filter size) must be an odd integer >= 1, got {gauss!r}")
    return int(gauss)


def prefilter(grey: np.ndarray, gauss: int) -> np.ndarray:
    """The float32 image as ECC compares it: smoothed by the gauss × gauss Gaussian OpenCV's ECC uses
    (σ from the size, as cv2.GaussianBlur chooses it); size 1 leaves it as it is."""
    img = grey.astype(np.float32, copy=False)
    return cv2.GaussianBlur(img, (gauss, gauss), 0) if gauss > 1 else img


def ecc_template(grey: np.ndarray, roi, gauss: int) -> np.ndarray:
    """The template for `find_transform`: the ROI cut from the pre-filtered whole frame."""
    x, y, w, h = roi
    return prefilter(grey, gauss)[y:y + h, x:x + w].copy()


def find_transform(template: np.ndarray, grey: np.ndarray, warp: np.ndarray, motion: int, criteria,
                   mask: np.ndarray | None, gauss: int) -> tuple[float, np.ndarray]:
    """cv2.findTransformECC of an `ecc_template` in the frame `grey` (pre-filtered here, whole, with the
    same size). Raises cv2.error as OpenCV does when it does not converge. A homography is handed over with
    h33 = 1: OpenCV's Jacobian of the homography takes h33 = 1 whatever the matrix holds (ecc.cpp), so a
    matrix scaled otherwise is refined along the wrong directions.

    A mask on the frame is used as given. OpenCV, when it filters, also drops the pixels within the filter's
    reach of a masked-out one; doing the same here measured worse where the mask is speckled by noise (warped
    photos with noise: median worst-corner error 0.11 → 0.14 px, p90 0.68 → 1.23 px) and slightly better under a
    walking occluder (0.266 → 0.254 px), so it is not done."""
    warp = np.array(warp, np.float32)
    if motion == cv2.MOTION_HOMOGRAPHY:
        warp /= warp[2, 2]
    return cv2.findTransformECC(template, prefilter(grey, gauss), warp, motion, criteria, mask, 1)
