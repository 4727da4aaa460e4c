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
# larger images are refused from their header, before decoding (a 30 000² "decompression bomb" would take GBs)
MAX_IMAGE_PIXELS = 64_000_000
ALPHA_BACKGROUND = 255  # transparent pixels are composited over white: the paper a picture is printed on


_BITS = {255: 8, 4095: 12, 65535: 16}
_NOTED: set = set()  # (what, range) pairs already reported: a folder of 16-bit frames gets one note, not one a frame


def _note_once(what: str, message: str, full: int) -> None:
    """Say once per kind of input and data range how a 16-bit image was reduced to 8 bit (a user must know)."""
    import logging

    if (what, full) not in _NOTED:
        _NOTED.add((what, full))
        logging.getLogger(__name__).warning("note: %s", message)


def read_rgb(path: str | Path, what: str = "image", whole: bool = False) -> np.ndarray:
    """H×W×3 uint8 RGB of an image file, read safely: a regular file only (not a FIFO or device), its size checked
    from the header before decoding (MAX_IMAGE_PIXELS), EXIF orientation applied, 16-bit images scaled by the
    range their values use (16-, 12- or 8-bit data in a 16-bit file), alpha composited over ALPHA_BACKGROUND.
    `whole`: decode it once more to prove it is complete (OpenCV fills a truncated JPEG with grey and goes on), for
    an image read once (a target), not a video's every frame. InputError saying what was wrong otherwise."""
    import warnings

    from PIL import Image

    p = Path(path)
    try:
        regular = p.is_file()
    except OSError as exc:  # a symlink loop, a name too long
        raise InputError(f"{what} {str(p)!r} cannot be opened ({exc.strerror or exc})") from None
    if not regular:
        raise InputError(f"{what} {str(p)!r} does not exist or is not a regular file")
    w = h = None
    alpha = False
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(p) as im:  # reads the header only
                (w, h), mode = im.size, im.mode
                alpha = mode in ("RGBA", "LA", "PA") or (mode == "P" and "transparency" in im.info)
    except Image.DecompressionBombError:
        raise InputError(f"{what} {str(p)!r} is larger than the {MAX_IMAGE_PIXELS:,} pixels accepted (by its "
                         "header); give a smaller image") from None
    except Exception:  # noqa: BLE001 - a format PIL does not know: OpenCV's verdict below, its size checked after
        w = h = None
    if whole and w is not None:
        _check_whole(p, what)
    if w is not None and w * h > MAX_IMAGE_PIXELS:  # type: ignore[operator]  # w and h are None together
        raise InputError(f"{what} {str(p)!r} is {w}×{h} px by its header, over the {MAX_IMAGE_PIXELS:,} pixels "
                         "accepted; give a smaller image")
    img = cv2.imread(str(p), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)  # EXIF orientation applied
    if img is None:
        raise InputError(f"cannot read {what} {str(p)!r}: accepted are images OpenCV reads ({', '.join(IMAGE_SUFFIXES)})")
    if img.dtype == np.uint16:
        top = int(img.max())
        full = 255 if top <= 255 else 4095 if top <= 4095 else 65535  # the range the data was written in
        img = np.clip(np.rint(img.astype(np.float64) * (255.0 / full)), 0, 255).astype(np.uint8)
        _note_once(what, f"{what} {str(p)!r} is a 16-bit image holding {_BITS[full]}-bit data (largest value {top}): "
                         f"scaled by 255/{full} to 8 bit (further {what}s of the same range are scaled alike)",
                   full)
    elif img.dtype != np.uint8:
        raise InputError(f"{what} {str(p)!r} holds {img.dtype} pixels; accepted: 8- or 16-bit images")
    if img.shape[0] * img.shape[1] > MAX_IMAGE_PIXELS:
        raise InputError(f"{what} {str(p)!r} is {img.shape[1]}×{img.shape[0]} px, over the {MAX_IMAGE_PIXELS:,} "
                         "pixels accepted; give a smaller image")
    rgb = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if alpha:
        raw = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if raw is not None and raw.ndim == 3 and raw.shape[2] == 4 and raw.shape[:2] == rgb.shape[:2]:
            a = raw[..., 3:].astype(np.float64) / (65535.0 if raw.dtype == np.uint16 else 255.0)
            rgb = np.rint(rgb * a + ALPHA_BACKGROUND * (1 - a)).astype(np.uint8)
    return rgb


def _check_whole(p: Path, what: str) -> None:
    """Decode the image with PIL, which (unlike OpenCV) refuses a file cut short."""
    from PIL import Image, ImageFile

    if ImageFile.LOAD_TRUNCATED_IMAGES:  # a setting of the process: then PIL cannot tell either
        return
    try:
        with Image.open(p) as im:
            im.load()
    except (OSError, SyntaxError, ValueError) as exc:
        raise InputError(f"{what} {str(p)!r} is truncated or damaged ({exc}); give the complete file") from None


def load_image(path: str | Path, what: str = "image", max_aspect: float | None = None) -> np.ndarray:
    """H×W×3 uint8 RGB from a PNG/JPEG/... file, shrunk to MAX_SIDE_PX; clear errors for bad files.

    max_aspect: refuse images longer than this many times their width, or the other way round.
    """
    p = Path(path)
    img = read_rgb(p, what, whole=True)
    h, w = img.shape[:2]
    if max_aspect is not None and max(h, w) > max_aspect * min(h, w):
        raise InputError(f"{what} {str(p)!r} is {w}×{h} px: accepted aspect ratios are 1:{max_aspect:g} to {max_aspect:g}:1")
    scale = min(1.0, MAX_SIDE_PX / max(h, w))
    if scale < 1:
        img = cv2.resize(img, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    if min(img.shape[:2]) < MIN_SIDE_PX:
        raise InputError(f"{what} {str(p)!r} is {w}×{h} px: too small to track; at least {MIN_SIDE_PX} px on each side")
    return img


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
