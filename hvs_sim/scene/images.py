"""User images for the wall: load, check and shape them for MuJoCo textures.

A target image keeps its aspect ratio; wall pictures are centre-cropped to the slot's 3:2. Large
images are shrunk (a 15 cm picture at 0.8 m covers ~110 px of a 640×480 frame, so 1024 texels
are plenty), and MuJoCo gets them as in-memory PNGs whatever format they came in.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from hvs_sim.errors import InputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
MIN_SIDE_PX = 32  # smaller than this cannot hold a template a tracker can lock on to
MAX_SIDE_PX = 1024  # texture size cap
TARGET_MAX_ASPECT = 4.0  # a target image may be at most 4:1 or 1:4 (a banner, not a ribbon)


def load_image(path: str | Path, what: str = "image", max_aspect: float | None = None) -> np.ndarray:
    """H×W×3 uint8 RGB from a PNG/JPEG/... file, shrunk to MAX_SIDE_PX; clear errors for bad files.

    max_aspect: refuse images longer than this many times their width, or the other way round.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{what} {str(p)!r} does not exist or is not a file")
    img = cv2.imread(str(p), cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"cannot read {what} {str(p)!r}: accepted are images OpenCV reads ({', '.join(IMAGE_SUFFIXES)})")
    h, w = img.shape[:2]
    if max_aspect is not None and max(h, w) > max_aspect * min(h, w):
        raise InputError(f"{what} {str(p)!r} is {w}×{h} px: accepted aspect ratios are 1:{max_aspect:g} to {max_aspect:g}:1")
    scale = min(1.0, MAX_SIDE_PX / max(h, w))
    if scale < 1:
        img = cv2.resize(img, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    if min(img.shape[:2]) < MIN_SIDE_PX:
        raise InputError(f"{what} {str(p)!r} is {w}×{h} px: too small to track; at least {MIN_SIDE_PX} px on each side")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def list_images(folder: str | Path) -> list[Path]:
    """Image files in a folder, sorted by name; an error if there are none."""
    d = Path(folder)
    if not d.is_dir():
        raise InputError(f"wall image folder {str(d)!r} does not exist or is not a folder")
    files = sorted(f for f in d.iterdir() if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputError(f"wall image folder {str(d)!r} holds no images ({', '.join(IMAGE_SUFFIXES)})")
    return files


def crop_to_aspect(img: np.ndarray, aspect: float) -> np.ndarray:
    """Centre crop to height / width = aspect (a poster trimmed to its frame)."""
    h, w = img.shape[:2]
    if h / w > aspect:
        ch = max(1, round(w * aspect))
        y0 = (h - ch) // 2
        return img[y0: y0 + ch]
    cw = max(1, round(h / aspect))
    x0 = (w - cw) // 2
    return img[:, x0: x0 + cw]
