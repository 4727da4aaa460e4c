"""Sample photographs the tests may track on: scikit-learn's and PyWavelets' images only.

scikit-image's and matplotlib's sample photographs (and one of OpenCV's sample clips) are reserved for independent evaluation
and never used in tests; `pywt.data.camera` is scikit-image's cameraman and is left out too.
"""

from functools import cache

import cv2
import numpy as np

SOURCES = {"china": ("sklearn", "china.jpg"), "flower": ("sklearn", "flower.jpg"),
           "ascent": ("pywt", "ascent"), "aero": ("pywt", "aero")}


@cache
def _source(name: str) -> np.ndarray:
    package, image = SOURCES[name]
    if package == "sklearn":
        from sklearn.datasets import load_sample_image

        img = load_sample_image(image)
    else:
        import pywt.data

        img = getattr(pywt.data, image)()
    img = np.clip(img, 0, 255).astype(np.uint8)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if img.ndim == 2 else img


def photo(name: str, size: tuple[int, int] = (640, 480)) -> np.ndarray:
    """The photo `name` as RGB uint8 resized to `size` (w, h); a fresh copy each call."""
    return cv2.resize(_source(name), size, interpolation=cv2.INTER_AREA)
