"""How well an image can be located by a template tracker: one measure that the scene's texture
sets (scene/textures.py) and the trackers' init check (tracking/trackability.py) both use."""

from __future__ import annotations

import math

import cv2
import numpy as np

TRACKABILITY_BLUR_SIGMA = 1.0


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
    img = np.asarray(img)
    grey = img.astype(np.float32)
    if grey.ndim == 3:
        grey = cv2.cvtColor(grey, cv2.COLOR_RGB2GRAY)
    if img.dtype == np.uint8:
        grey /= 255.0
    grey = cv2.GaussianBlur(grey, (0, 0), TRACKABILITY_BLUR_SIGMA)
    ix = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=1) * 0.5
    iy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=1) * 0.5
    a, b, d = float(np.mean(ix * ix)), float(np.mean(ix * iy)), float(np.mean(iy * iy))
    return 0.5 * (a + d) - math.sqrt(0.25 * (a - d) ** 2 + b * b)
