"""Photo families: seeded crops of the scikit-learn and PyWavelets sample photos (see the package docstring
for which photos may be used), loaded once and lazily.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from hvs_sim.scene.textures.base import _Canvas

# ---------------------------------------------------------------------------------------------------------------------
# Photographs
# ---------------------------------------------------------------------------------------------------------------------

PHOTO_SOURCES = {  # name -> (package, image)
    "photo_china": ("sklearn", "china.jpg"),
    "photo_flower": ("sklearn", "flower.jpg"),
    "photo_aero": ("pywt", "aero"),
    "photo_ascent": ("pywt", "ascent"),
}
PHOTO_CROP = (0.55, 0.95)  # crop side as a fraction of the largest crop with the requested aspect ratio
GREY_TINT = 0.05  # grey photos get a mild warm or cool cast per seed (white balance of a print under a lamp)


@functools.cache
def _photo_source(name: str) -> np.ndarray:
    """The full photo as RGB uint8 (grey sources as H×W), loaded once; imports are lazy (sklearn is slow)."""
    package, image = PHOTO_SOURCES[name]
    if package == "sklearn":
        from sklearn.datasets import load_sample_image

        img = load_sample_image(image)
    else:
        import pywt.data

        img = getattr(pywt.data, image)()
    img = np.ascontiguousarray(img, dtype=np.uint8)
    img.setflags(write=False)
    return img


def _photo(name: str, c: _Canvas) -> np.ndarray:
    """A seeded crop (position and size) of a photo, resized to the canvas; grey photos get a mild tint."""
    rng, h, w = c.rng, c.h, c.w
    src = _photo_source(name)
    sh, sw = src.shape[:2]
    aspect = w / h
    max_w = min(sw, sh * aspect)
    crop_w = max_w * rng.uniform(*PHOTO_CROP)
    crop_h = crop_w / aspect
    x0 = int(rng.uniform(0, sw - crop_w))
    y0 = int(rng.uniform(0, sh - crop_h))
    crop = src[y0:y0 + max(int(crop_h), 1), x0:x0 + max(int(crop_w), 1)]
    shrink = crop.shape[1] > w
    img = cv2.resize(crop, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_CUBIC)
    if img.ndim == 2:
        warmth = rng.uniform(-GREY_TINT, GREY_TINT)
        tint = np.array([1 + warmth, 1.0, 1 - warmth], np.float32)
        return img.astype(np.float32)[..., None] * tint
    return img.astype(np.float32)
