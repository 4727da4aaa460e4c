"""Procedural noise and weave primitives of the scene, kept in one place: the wall's natural textures
(`hvs_sim/scene/textures/`) and the people's fabrics, skin and hair (`hvs_sim/scene/people/`) are drawn with them.

Two noise families live here side by side and are deliberately not merged: they give different arrays, so
replacing one with the other would change every texture or every person.

- `value_noise`, `fbm`, `turbulence`, `standardise` (the wall textures): a random lattice upsampled bicubically
  and cropped at a random offset. Any size, float32, does not tile.
- `periodic_noise` (the people's cloth, skin and hair): white noise low-passed in the Fourier domain. It tiles
  seamlessly, as a texture wrapped round a body part must, and normalises with a smaller epsilon.

`weave_over` is shared: both the wall's woven fabric and the people's woven cloth decide with it which yarn lies
on top at each crossing (plain weave, 3/1 and 2/2 twill, herringbone).
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.errors import choice_error

HERRINGBONE_BAND = 8  # yarns between turns of a herringbone's diagonal
WEAVES = ("plain", "twill31", "twill22", "herringbone")


# ------------------------------------------------------------------------------------------------
# Value noise: the wall textures' octaves (non-tiling)


def value_noise(rng: np.random.Generator, h: int, w: int, cell_px: float, aspect: float = 1.0) -> np.ndarray:
    """One octave of smooth value noise, features about `cell_px` wide and `aspect` times as tall.

    A random lattice is upsampled bicubically and cropped at a random sub-cell offset, so octaves do
    not share grid lines.
    """
    cx = max(float(cell_px), 1.0)
    cy = max(float(cell_px) * aspect, 1.0)
    nx, ny = int(w / cx) + 3, int(h / cy) + 3
    lattice = rng.standard_normal((ny, nx), dtype=np.float32)
    big = cv2.resize(lattice, (max(round(nx * cx), w), max(round(ny * cy), h)), interpolation=cv2.INTER_CUBIC)
    ox = int(rng.integers(0, big.shape[1] - w + 1))
    oy = int(rng.integers(0, big.shape[0] - h + 1))
    return big[oy:oy + h, ox:ox + w]


def standardise(x: np.ndarray) -> np.ndarray:
    return (x - x.mean()) / (x.std() + 1e-6)


def fbm(rng, h, w, cell_px, octaves=5, gain=0.5, aspect=1.0) -> np.ndarray:
    """Fractal (1/f-like) noise: octaves of value noise halving in size, zero mean and unit std."""
    total = np.zeros((h, w), np.float32)
    amp = 1.0
    for i in range(octaves):
        cell = cell_px / 2 ** i
        if cell < 1.0:
            break
        total += amp * value_noise(rng, h, w, cell, aspect)
        amp *= gain
    return standardise(total)


def turbulence(rng, h, w, cell_px, octaves=5) -> np.ndarray:
    """Perlin's turbulence: octaves of |noise|, creased where each octave crosses zero; zero mean, unit std."""
    total = np.zeros((h, w), np.float32)
    for i in range(octaves):
        cell = cell_px / 2 ** i
        if cell < 1.0:
            break
        total += np.abs(value_noise(rng, h, w, cell)) / 2 ** i
    return standardise(total)


# ------------------------------------------------------------------------------------------------
# Periodic noise: the people's cloth, skin and hair (tiles seamlessly)


def periodic_noise(rng: np.random.Generator, shape: tuple[int, int], scale_px: float,
                   stretch: float = 1.0) -> np.ndarray:
    """Zero-mean, unit-std smooth noise that tiles seamlessly (white noise low-passed by FFT).

    `stretch` > 1 elongates the blobs vertically (yarn slubs, hair strands).
    """
    h, w = shape
    white = rng.standard_normal((h, w), dtype=np.float32)
    fy = np.fft.fftfreq(h)[:, None] * scale_px * stretch
    fx = np.fft.rfftfreq(w)[None, :] * scale_px
    out = np.fft.irfft2(np.fft.rfft2(white) * np.exp(-2.0 * np.pi ** 2 * (fx ** 2 + fy ** 2)), s=(h, w))
    return (out - out.mean()) / (out.std() + 1e-12)


# ------------------------------------------------------------------------------------------------
# Weaves: shared by the wall's woven fabric and the people's woven cloth


def weave_over(weft: np.ndarray, warp: np.ndarray, weave: str) -> np.ndarray:
    """bool, elementwise: True where the warp (vertical yarn) lies on top of the weft (horizontal yarn).

    weft, warp: integer yarn indices (any shape, negative ones too), e.g. the rows and columns of
    `np.mgrid[0:n, 0:n]` for a tile of n × n yarns.
    """
    if weave == "plain":
        return (weft + warp) % 2 == 0
    if weave == "twill31":  # denim: warp floats over three wefts, a steep diagonal rib
        return (weft + warp) % 4 != 0
    if weave == "twill22":
        return (weft + warp) % 4 < 2
    if weave == "herringbone":  # a 2/2 twill whose diagonal turns every HERRINGBONE_BAND warp yarns
        flip = (warp // HERRINGBONE_BAND) % 2 == 1
        return np.where(flip, (weft - warp) % 4 < 2, (weft + warp) % 4 < 2)
    raise choice_error("weave", weave, WEAVES)
