"""Procedural flags for the flag wall: 15 distinct designs with a woven-fabric print texture.

Run `python -m hvs_sim.scene.flag_art` to (re)write assets/flags/*.png. The images are a pure
function of the design name, so the committed PNGs can be checked against this code.
"""

from __future__ import annotations

import zlib
from pathlib import Path

import cv2
import numpy as np

from hvs_sim.errors import choice_error

FLAG_SIZE = (300, 200)  # (width, height) in texels, the 3:2 aspect of the flag geoms

# Colours are RGB.
RED, WHITE, BLUE = (200, 16, 46), (245, 245, 240), (0, 56, 147)
GREEN, YELLOW, BLACK = (0, 122, 61), (252, 209, 22), (25, 25, 25)
ORANGE, SKY, MAROON = (255, 130, 0), (117, 170, 219), (128, 0, 32)


def _canvas(color) -> np.ndarray:
    w, h = FLAG_SIZE
    img = np.empty((h, w, 3), np.uint8)
    img[:] = color
    return img


def _star(img, center, radius, color, points=5, inner=0.4, rot=-np.pi / 2):
    angles = rot + np.arange(2 * points) * np.pi / points
    radii = np.where(np.arange(2 * points) % 2 == 0, radius, radius * inner)
    pts = np.stack([center[0] + radii * np.cos(angles), center[1] + radii * np.sin(angles)], 1)
    cv2.fillPoly(img, [np.round(pts).astype(np.int32)], color, cv2.LINE_AA)


def _hstripes(colors):
    img = _canvas(colors[0])
    h = FLAG_SIZE[1]
    for i, c in enumerate(colors):
        img[i * h // len(colors):(i + 1) * h // len(colors)] = c
    return img


def _vstripes(colors):
    img = _canvas(colors[0])
    w = FLAG_SIZE[0]
    for i, c in enumerate(colors):
        img[:, i * w // len(colors):(i + 1) * w // len(colors)] = c
    return img


def _nordic():
    img = _canvas(BLUE)
    cv2.rectangle(img, (80, 0), (125, 199), YELLOW, -1)
    cv2.rectangle(img, (0, 78), (299, 122), YELLOW, -1)
    return img


def _saltire():
    img = _canvas(WHITE)
    cv2.line(img, (0, 0), (299, 199), RED, 34, cv2.LINE_AA)
    cv2.line(img, (0, 199), (299, 0), RED, 34, cv2.LINE_AA)
    cv2.rectangle(img, (0, 0), (299, 199), BLUE, 10)
    return img


def _disc():
    img = _canvas(WHITE)
    cv2.circle(img, (130, 100), 58, RED, -1, cv2.LINE_AA)
    cv2.rectangle(img, (0, 185), (299, 199), BLACK, -1)
    return img


def _star_field():
    img = _canvas(RED)
    _star(img, (75, 70), 48, YELLOW)
    for k, (x, y) in enumerate([(150, 25), (180, 55), (182, 100), (155, 135)]):
        _star(img, (x, y), 16, YELLOW, rot=-np.pi / 2 + 0.3 * k)
    return img


def _chevron():
    img = _hstripes([BLACK, WHITE, GREEN])
    cv2.fillPoly(img, [np.array([[0, 0], [120, 100], [0, 199]], np.int32)], RED, cv2.LINE_AA)
    return img


def _diagonal():
    img = _canvas(GREEN)
    cv2.fillPoly(img, [np.array([[0, 199], [299, 0], [299, 199]], np.int32)], BLUE, cv2.LINE_AA)
    cv2.line(img, (0, 199), (299, 0), YELLOW, 30, cv2.LINE_AA)
    _star(img, (60, 55), 26, WHITE)
    return img


def _quartered():
    img = _canvas(WHITE)
    img[:100, 150:] = MAROON
    img[100:, :150] = MAROON
    cv2.circle(img, (150, 100), 30, YELLOW, -1, cv2.LINE_AA)
    return img


def _triangle_hoist():
    img = _hstripes([SKY, WHITE, SKY])
    cv2.fillPoly(img, [np.array([[0, 0], [170, 100], [0, 199]], np.int32)], BLUE, cv2.LINE_AA)
    _star(img, (55, 100), 24, WHITE)
    return img


def _canton_stripes():
    img = _canvas(WHITE)
    for i in range(0, 13, 2):
        img[i * 200 // 13:(i + 1) * 200 // 13] = RED
    img[:108, :130] = BLUE
    for r in range(4):
        for c in range(5):
            cv2.circle(img, (15 + 25 * c + 12 * (r % 2), 15 + 25 * r), 5, WHITE, -1, cv2.LINE_AA)
    return img


def _crescent():
    img = _canvas(GREEN)
    img[:, :75] = WHITE
    cv2.circle(img, (175, 100), 50, WHITE, -1, cv2.LINE_AA)
    cv2.circle(img, (192, 92), 42, GREEN, -1, cv2.LINE_AA)
    _star(img, (225, 75), 16, WHITE, rot=-0.3)
    return img


def _cross_quarters():
    img = _canvas(RED)
    cv2.rectangle(img, (125, 0), (175, 199), WHITE, -1)
    cv2.rectangle(img, (0, 75), (299, 125), WHITE, -1)
    for x, y in [(60, 35), (240, 35), (60, 165), (240, 165)]:
        cv2.circle(img, (x, y), 14, YELLOW, -1, cv2.LINE_AA)
    return img


def _rings():
    img = _canvas(ORANGE)
    for r, c in [(80, BLACK), (60, WHITE), (40, BLUE), (20, YELLOW)]:
        cv2.circle(img, (210, 100), r, c, -1, cv2.LINE_AA)
    cv2.rectangle(img, (0, 0), (60, 199), BLACK, -1)
    return img


def _checker_band():
    img = _hstripes([YELLOW, BLACK, YELLOW])
    for c in range(10):
        if c % 2 == 0:
            img[70:130, c * 30:(c + 1) * 30] = WHITE
    cv2.putText(img, "H7", (20, 55), cv2.FONT_HERSHEY_DUPLEX, 1.6, RED, 3, cv2.LINE_AA)
    return img


_DESIGNS = {
    "tricolor_h": lambda: _hstripes([BLACK, RED, YELLOW]),
    "tricolor_v": lambda: _vstripes([BLUE, WHITE, RED]),
    "nordic_cross": _nordic,
    "saltire": _saltire,
    "disc": _disc,
    "star_field": _star_field,
    "chevron": _chevron,
    "diagonal": _diagonal,
    "quartered": _quartered,
    "triangle_hoist": _triangle_hoist,
    "canton_stripes": _canton_stripes,
    "crescent": _crescent,
    "cross_quarters": _cross_quarters,
    "rings": _rings,
    "checker_band": _checker_band,
}
FLAG_NAMES: tuple[str, ...] = tuple(_DESIGNS)


def fabric(img: np.ndarray, seed: int) -> np.ndarray:
    """Add a weave, soft folds and print noise so that flags are not flat colour."""
    h, w = img.shape[:2]
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    weave = 0.05 * np.sin(2 * np.pi * x / 3.0) * np.sin(2 * np.pi * y / 3.0)
    phase = rng.uniform(0, 2 * np.pi, 2)
    folds = 0.08 * np.sin(2 * np.pi * x / w * 1.5 + phase[0]) * np.cos(2 * np.pi * y / h * 0.7 + phase[1])
    noise = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 1.2) * 0.06
    gain = (1.0 + weave + folds + noise)[..., None]
    return np.clip(img.astype(np.float32) * gain + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)


def draw_flag(name: str) -> np.ndarray:
    """RGB uint8 image (200×300) of the named flag, fabric texture included."""
    if name not in _DESIGNS:
        raise choice_error("flag", name, FLAG_NAMES)
    return fabric(_DESIGNS[name](), seed=zlib.crc32(name.encode()))


def flag_path(name: str, directory: Path | None = None) -> Path:
    from hvs_sim.paths import FLAGS_DIR

    return (directory or FLAGS_DIR) / f"{name}.png"


def write_flags(directory: Path | None = None) -> list[Path]:
    """Write every flag as PNG into `directory` (default assets/flags)."""
    paths = []
    for name in FLAG_NAMES:
        path = flag_path(name, directory)
        path.parent.mkdir(parents=True, exist_ok=True)
        from hvs_sim.outputs import write_image

        write_image(path, cv2.cvtColor(draw_flag(name), cv2.COLOR_RGB2BGR))
        paths.append(path)
    return paths


if __name__ == "__main__":
    for p in write_flags():
        print(p)
