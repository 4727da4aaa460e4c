"""The texture registry and public API: names, texture sets, `natural_texture`, and the contact sheet.

`write_contact_sheet` lives beside `natural_texture` so that it looks the generator up in this module.
"""

from __future__ import annotations

import zlib
from pathlib import Path
from types import MappingProxyType

import cv2
import numpy as np

from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.scene.textures.base import MAX_SIDE, MIN_SIDE, _Canvas, _to_uint8
from hvs_sim.scene.textures.manmade import _corkboard, _fabric, _mosaic, _poster
from hvs_sim.scene.textures.materials import (
    _bark,
    _brick,
    _clouds,
    _foliage,
    _fur,
    _granite,
    _gravel,
    _marble,
    _sand,
    _wood,
)
from hvs_sim.scene.textures.photos import PHOTO_SOURCES, _photo

# ---------------------------------------------------------------------------------------------------------------------
# Registry and public API
# ---------------------------------------------------------------------------------------------------------------------

_PROCEDURAL = {
    "wood": _wood,
    "marble": _marble,
    "brick": _brick,
    "gravel": _gravel,
    "foliage": _foliage,
    "fur": _fur,
    "bark": _bark,
    "clouds": _clouds,
    "granite": _granite,
    "sand": _sand,
    "poster": _poster,
    "mosaic": _mosaic,
    "fabric": _fabric,
    "corkboard": _corkboard,
}
PROCEDURAL_TEXTURES: tuple[str, ...] = tuple(_PROCEDURAL)
PHOTO_TEXTURES: tuple[str, ...] = tuple(PHOTO_SOURCES)
NATURAL_TEXTURES: tuple[str, ...] = PROCEDURAL_TEXTURES + PHOTO_TEXTURES

TEXTURE_SETS = MappingProxyType({
    # every texture: the default variety for walls and training data
    "natural": NATURAL_TEXTURES,
    # numpy/OpenCV materials only: no package data needed, unlimited seeds
    "procedural": PROCEDURAL_TEXTURES,
    # crops of real photographs (scikit-learn, PyWavelets)
    "photos": PHOTO_TEXTURES,
    # the same pattern everywhere, at every scale: a lost tracker cannot re-acquire by global search
    "self_similar": ("fur", "foliage", "brick", "gravel", "fabric"),
    # little 2-D structure (smooth sky, fine sand, grain in one direction): the target itself is barely
    # trackable; trackability() below ~2e-4 at 256 px
    "low_texture": ("clouds", "sand", "wood"),
    # man-made printed matter, like posters and notices on an office wall
    "printed": ("poster", "corkboard") + PHOTO_TEXTURES,
})


def texture_set(name: str) -> tuple[str, ...]:
    """The texture names of a set in TEXTURE_SETS."""
    if name not in TEXTURE_SETS:
        raise choice_error("texture set", name, TEXTURE_SETS)
    return TEXTURE_SETS[name]


def _check_int(what: str, value, low: int, high: int | None = None) -> int:
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if not ok or value < low or (high is not None and value > high):
        accepted = f"an integer in [{low}, {high}]" if high is not None else f"an integer >= {low}"
        raise ConfigError(f"texture {what} must be {accepted}, got {value!r}")
    return int(value)


def natural_texture(name: str, width: int = 512, height: int = 512, seed: int = 0) -> np.ndarray:
    """height × width × 3 RGB uint8 image of texture `name` (see NATURAL_TEXTURES).

    Deterministic per (name, size, seed); different seeds give different instances (layout, palette,
    crop). Width and height are integers in [MIN_SIDE, MAX_SIDE]; seed is an integer >= 0.
    """
    if name not in NATURAL_TEXTURES:
        raise choice_error("texture", name, NATURAL_TEXTURES)
    w = _check_int("width", width, MIN_SIDE, MAX_SIDE)
    h = _check_int("height", height, MIN_SIDE, MAX_SIDE)
    seed = _check_int("seed", seed, 0)
    canvas = _Canvas(np.random.default_rng([zlib.crc32(name.encode()), seed]), h, w)
    img = _photo(name, canvas) if name in PHOTO_SOURCES else _PROCEDURAL[name](canvas)
    return _to_uint8(img)


# ---------------------------------------------------------------------------------------------------------------------
# Trackability and contact sheet
# ---------------------------------------------------------------------------------------------------------------------


SHEET_LABEL_PX = 22
SHEET_COLUMNS = 8


def write_contact_sheet(path, names=None, seeds=(0, 1), size: int = 256) -> Path:
    """Write a labelled grid of textures (each name at each seed) as an image; returns the path."""
    names = NATURAL_TEXTURES if names is None else tuple(names)
    tiles = []
    for name in names:
        for seed in seeds:
            tile = np.full((size + SHEET_LABEL_PX, size, 3), 255, np.uint8)
            tile[SHEET_LABEL_PX:] = natural_texture(name, size, size, seed)
            cv2.putText(tile, f"{name} s{seed}", (4, SHEET_LABEL_PX - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1,
                        cv2.LINE_AA)
            tiles.append(tile)
    cols = min(SHEET_COLUMNS, len(tiles))
    blank = np.full_like(tiles[0], 255)
    tiles += [blank] * (-len(tiles) % cols)
    rows = [np.concatenate(tiles[r:r + cols], 1) for r in range(0, len(tiles), cols)]
    sheet = np.concatenate(rows, 0)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    from hvs_sim.outputs import write_image

    write_image(path, cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    return path
