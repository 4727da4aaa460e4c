"""Sample photographs the tests may track on: scikit-learn's and PyWavelets' images only, loaded as the scene's photo
textures load them (hvs_sim.scene.textures.photos).

scikit-image's and matplotlib's sample photographs (and one of OpenCV's sample clips) are reserved for independent
evaluation and never used in tests; `pywt.data.camera` is scikit-image's cameraman and is left out too.
"""

import cv2
import numpy as np

from hvs_sim.scene.textures.photos import _photo_source


def photo(name: str, size: tuple[int, int] = (640, 480)) -> np.ndarray:
    """The photo `name` (china, flower, ascent or aero) as RGB uint8 resized to `size` (w, h); a fresh copy each call."""
    img = cv2.resize(_photo_source(f"photo_{name}"), size, interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if img.ndim == 2 else img
