"""Natural-looking textures for the wall: procedural materials and crops of freely licensed photos.

Clean flags flatter every tracker; real walls carry wood, brick, posters, notice boards, plants and
fur-like surfaces whose texture repeats at every scale. `natural_texture(name, width, height, seed)`
returns an RGB uint8 image, a pure function of its arguments, so scenes and training sets built from
it are reproducible.

Procedural families use numpy + OpenCV only: fractal noise (sums of octaves of seeded value noise),
domain warping, jittered-grid Voronoi cells, line-integral convolution along a flow field, and
palettes read off photographs of the real materials. Feature sizes are given in pixels of a 512 px
image and scale with sqrt(width * height), so a texture keeps its look at other sizes.

Photo families crop the scikit-learn sample photos (china, flower) and the PyWavelets images
(aero, ascent). scikit-image's and matplotlib's sample photos are kept for a held-out evaluation and
must never be used here. There is no `photo_face`: PyWavelets (1.9) ships no face image (pywt.data
has aero, ascent, camera, ecg, nino), and `pywt.data.camera` is scikit-image's cameraman, excluded.
"""

from __future__ import annotations

import functools
import math
import zlib
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import cv2
import numpy as np

from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.texture_measure import trackability  # noqa: F401  (re-exported: texture sets are ranked by it)

# ---------------------------------------------------------------------------------------------------------------------
# Shared building blocks
# ---------------------------------------------------------------------------------------------------------------------

REF_SIZE = 512.0  # feature sizes below are in pixels of a REF_SIZE × REF_SIZE image
MIN_SIDE, MAX_SIDE = 32, 4096
LIGHT = np.array([-0.45, -0.55, 0.70], np.float32)  # light from the upper left, like a ceiling lamp
LIGHT /= np.linalg.norm(LIGHT)

Rgb = tuple[int, int, int]


@dataclass(frozen=True)
class _Canvas:
    """What a generator needs: its random stream, the size, and pixels per reference pixel."""

    rng: np.random.Generator
    h: int
    w: int

    @property
    def s(self) -> float:
        return math.sqrt(self.h * self.w) / REF_SIZE


def _grid(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    return xs, ys


def _noise(rng: np.random.Generator, h: int, w: int, cell_px: float, aspect: float = 1.0) -> np.ndarray:
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


def _standardise(x: np.ndarray) -> np.ndarray:
    return (x - x.mean()) / (x.std() + 1e-6)


def _fbm(rng, h, w, cell_px, octaves=5, gain=0.5, aspect=1.0) -> np.ndarray:
    """Fractal (1/f-like) noise: octaves of value noise halving in size, zero mean and unit std."""
    total = np.zeros((h, w), np.float32)
    amp = 1.0
    for i in range(octaves):
        cell = cell_px / 2 ** i
        if cell < 1.0:
            break
        total += amp * _noise(rng, h, w, cell, aspect)
        amp *= gain
    return _standardise(total)


def _turbulence(rng, h, w, cell_px, octaves=5) -> np.ndarray:
    """Perlin's turbulence: octaves of |noise|, creased where each octave crosses zero; zero mean, unit std."""
    total = np.zeros((h, w), np.float32)
    for i in range(octaves):
        cell = cell_px / 2 ** i
        if cell < 1.0:
            break
        total += np.abs(_noise(rng, h, w, cell)) / 2 ** i
    return _standardise(total)


def _remap(img: np.ndarray, map_x: np.ndarray, map_y: np.ndarray) -> np.ndarray:
    map_x, map_y = map_x.astype(np.float32, copy=False), map_y.astype(np.float32, copy=False)
    return cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101)


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _lerp(a, b, t: np.ndarray) -> np.ndarray:
    """Per-pixel blend of colours (or colour images) `a` -> `b` by weight map `t`."""
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    return a + (b - a) * t[..., None]


def _shade(height: np.ndarray, relief: float = 1.0) -> np.ndarray:
    """Lambert shading of a height map (in px) lit by LIGHT; 1.0 on flat ground."""
    gx = cv2.Sobel(height, cv2.CV_32F, 1, 0, ksize=3) * (relief / 8.0)
    gy = cv2.Sobel(height, cv2.CV_32F, 0, 1, ksize=3) * (relief / 8.0)
    dot = (-gx * LIGHT[0] - gy * LIGHT[1] + LIGHT[2]) / np.sqrt(1.0 + gx * gx + gy * gy)
    return np.clip(dot / LIGHT[2], 0.0, 2.0)


def _voronoi(rng, xs: np.ndarray, ys: np.ndarray, cell_px: float, jitter: float = 1.0):
    """Jittered-grid Voronoi cells of (possibly warped) coordinates.

    Returns (F1, F2, cell id, number of ids): distances in px to the nearest and second-nearest
    site and an index into per-cell attribute arrays the caller draws. F2 - F1 is about twice the
    distance to the cell border, the usual handle for pebbles, crystals and cracks.
    """
    gx, gy = xs / cell_px, ys / cell_px
    x0, y0 = int(np.floor(gx.min())) - 1, int(np.floor(gy.min())) - 1
    nx, ny = int(np.floor(gx.max())) - x0 + 2, int(np.floor(gy.max())) - y0 + 2
    site_x = (np.arange(nx, dtype=np.float32)[None, :] + x0 + 0.5
              + (rng.random((ny, nx), dtype=np.float32) - 0.5) * jitter).ravel()
    site_y = (np.arange(ny, dtype=np.float32)[:, None] + y0 + 0.5
              + (rng.random((ny, nx), dtype=np.float32) - 0.5) * jitter).ravel()
    ci = np.floor(gx).astype(np.int32) - x0
    cj = np.floor(gy).astype(np.int32) - y0
    f1 = np.full(gx.shape, np.inf, np.float32)
    f2 = f1.copy()
    ids = np.zeros(gx.shape, np.int32)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            flat = np.clip(cj + dj, 0, ny - 1) * nx + np.clip(ci + di, 0, nx - 1)
            d = (gx - site_x[flat]) ** 2 + (gy - site_y[flat]) ** 2
            closer = d < f1
            f2 = np.where(closer, f1, np.minimum(f2, d))
            ids = np.where(closer, flat, ids)
            f1 = np.where(closer, d, f1)
    return np.sqrt(f1) * cell_px, np.sqrt(f2) * cell_px, ids, nx * ny


def _pick(rng, palette, n: int, weights=None, spread: float = 0.0) -> np.ndarray:
    """n colours drawn from a palette (optionally weighted), each scaled by 1 + N(0, spread)."""
    cols = np.asarray(palette, np.float32)
    p = None if weights is None else np.asarray(weights, np.float64) / np.sum(weights)
    out = cols[rng.choice(len(cols), n, p=p)]
    return out * (1.0 + spread * rng.standard_normal((n, 1))).astype(np.float32)


def _to_uint8(img: np.ndarray) -> np.ndarray:
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def _sprinkle(rng, img: np.ndarray, sigma: float) -> np.ndarray:
    """Sensor-like per-pixel noise so that no texture has perfectly flat areas."""
    return img + rng.normal(0.0, sigma, img.shape[:2]).astype(np.float32)[..., None]


# ---------------------------------------------------------------------------------------------------------------------
# Wood
# ---------------------------------------------------------------------------------------------------------------------

WOOD_SPECIES: tuple[tuple[Rgb, Rgb], ...] = (  # (earlywood, latewood) RGB of planed boards
    ((210, 166, 112), (128, 82, 44)),  # oak
    ((232, 198, 148), (170, 108, 56)),  # pine
    ((136, 92, 62), (58, 36, 22)),  # walnut
    ((194, 116, 74), (110, 52, 30)),  # cherry
)
WOOD_PLANKS = (3, 6)  # boards across the image
WOOD_RING_PX = (6.0, 14.0)  # growth-ring spacing
WOOD_RING_STRETCH = (0.04, 0.25)  # rings are ellipses 4-25 times as tall as wide: long grain, cathedral arches
WOOD_GAP_PX = 1.5
WOOD_PORE_ASPECT = 6.0  # pores are short dashes along the grain, not endless lines
WOOD_LATEWOOD_POWER = 1.8  # earlywood darkens slowly into latewood, then the next ring starts light


def _wood(c: _Canvas) -> np.ndarray:
    """Boards of flat-sawn wood: warped growth rings of varying width, pore streaks, seams, end joints."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    light, dark = WOOD_SPECIES[rng.integers(len(WOOD_SPECIES))]
    n = int(rng.integers(*WOOD_PLANKS))
    edges = np.linspace(0, w, n + 1) + np.r_[0, rng.uniform(-0.15, 0.15, n - 1) * w / n, 0]
    xs, ys = _grid(h, w)
    plank = np.searchsorted(edges[1:-1], xs[0])[None, :]
    centre = 0.5 * (edges[:-1] + edges[1:])
    pith_x = centre + rng.choice([-1, 1], n) * rng.uniform(0.3, 2.0, n) * w / n
    pith_y = rng.uniform(0.0, 1.0, n) * h
    stretch = rng.uniform(*WOOD_RING_STRETCH, n)
    ring = rng.uniform(*WOOD_RING_PX, n) * s
    joint = np.where(rng.random(n) < 0.6, rng.uniform(0.1, 0.9, n) * h, -1e9)
    past_joint = ys > joint[plank]
    dx = xs - pith_x[plank]
    dy = (ys - pith_y[plank]) * stretch[plank]
    warp = _fbm(rng, h, w, 140 * s, 4, aspect=3.0)
    years = _fbm(rng, h, w, 50 * s, 2, aspect=4.0)  # wet and dry years: uneven ring widths
    r = np.sqrt(dx * dx + dy * dy) / ring[plank] + 0.9 * warp + 0.25 * years + past_joint * 3.7
    late = (r - np.floor(r)) ** WOOD_LATEWOOD_POWER
    pores = _noise(rng, h, w, 1.0 * s, aspect=WOOD_PORE_ASPECT)
    streaks = _noise(rng, h, w, 3.0 * s, aspect=12.0)
    figure = _fbm(rng, h, w, 160 * s, 3)
    tone = np.clip(0.72 * late + 0.12 * pores + 0.07 * streaks + 0.07 * figure + 0.03, 0, 1)
    tint = rng.normal(1.0, 0.07, n).astype(np.float32)
    img = _lerp(light, dark, tone) * tint[plank][..., None]
    seam_x = np.abs(xs[0][None, :] - edges[:, None]).min(0)[None, :]
    seam = np.minimum(seam_x, np.abs(ys - joint[plank]))
    img *= (0.35 + 0.65 * _smoothstep(0.0, WOOD_GAP_PX * s, seam))[..., None]
    return _sprinkle(rng, img, 2.0)


# ---------------------------------------------------------------------------------------------------------------------
# Marble
# ---------------------------------------------------------------------------------------------------------------------

MARBLE_STONES: tuple[tuple[Rgb, Rgb, Rgb], ...] = (  # (ground, clouding, vein)
    ((236, 234, 229), (212, 211, 208), (96, 98, 104)),  # Carrara
    ((242, 237, 226), (224, 214, 196), (150, 118, 76)),  # Calacatta
    ((34, 33, 35), (52, 50, 52), (226, 222, 214)),  # Nero Marquina
    ((46, 86, 66), (28, 60, 44), (206, 224, 208)),  # Verde Alpi
    ((196, 124, 112), (168, 92, 84), (240, 214, 204)),  # Rosso Levanto
)
MARBLE_VEIN_PERIOD_PX = (220.0, 400.0)  # spacing of the main veins across their run: 1-3 per image
MARBLE_TURBULENCE = 0.45  # how far (in vein periods) fractal noise bends the veins
MARBLE_VEIN_WIDTH = 0.05  # of the vein field's half period: ~2-4 px veins at 512 px


def _marble(c: _Canvas) -> np.ndarray:
    """Polished marble: long veins (zero-crossings of a sine bent by fractal turbulence) of varying
    width over cloudy ground, plus a net of thin secondary veins."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    ground, cloud, vein = MARBLE_STONES[rng.integers(len(MARBLE_STONES))]
    xs, ys = _grid(h, w)
    phi = rng.uniform(0, np.pi)
    period = rng.uniform(*MARBLE_VEIN_PERIOD_PX) * s
    across = (xs * math.cos(phi) + ys * math.sin(phi)) / period
    field = np.sin(np.pi * (across + MARBLE_TURBULENCE * _turbulence(rng, h, w, 300 * s, 5)))
    width = MARBLE_VEIN_WIDTH * (0.2 + 1.6 * _smoothstep(-1.2, 1.5, _fbm(rng, h, w, 120 * s, 3)))
    fade = 0.3 + 0.7 * _smoothstep(-1.0, 0.5, _fbm(rng, h, w, 200 * s, 3))  # veins come and go
    veins = np.exp(-(field / width) ** 2) * fade
    halo = np.exp(-(field / (6 * width)) ** 2)
    qx, qy = (_fbm(rng, h, w, 150 * s, 3) * 25 * s for _ in range(2))
    fine = _remap(_fbm(rng, h, w, 110 * s, 4), xs + qx, ys + qy)
    near_vein = np.exp(-(field / 0.5) ** 2)  # secondary veins branch off near the main ones
    thin = np.exp(-(fine / 0.04) ** 2) * near_vein * _smoothstep(-0.5, 1.0, _fbm(rng, h, w, 200 * s, 2))
    clouding = _smoothstep(-1.0, 1.5, _fbm(rng, h, w, 140 * s, 6, gain=0.6))
    img = _lerp(ground, cloud, clouding)
    weight = np.clip(0.9 * veins + 0.25 * halo + 0.5 * thin, 0, 1)
    img = _lerp(img, vein, weight)
    return _sprinkle(rng, img, 1.5)


# ---------------------------------------------------------------------------------------------------------------------
# Brick
# ---------------------------------------------------------------------------------------------------------------------

BRICK_PALETTES: tuple[tuple[Rgb, ...], ...] = (
    ((150, 62, 42), (166, 78, 52), (132, 54, 38), (178, 96, 64), (112, 46, 34), (150, 84, 62)),  # red
    ((196, 160, 110), (180, 140, 92), (160, 120, 80), (206, 176, 132), (140, 102, 72)),  # yellow stock
    ((112, 72, 54), (92, 60, 46), (132, 86, 62), (76, 52, 42), (120, 96, 80)),  # engineering brown
)
MORTAR_RGB: Rgb = (176, 170, 158)
BRICK_PX = (84.0, 28.0)  # (length, course height) including one mortar joint
MORTAR_PX = 5.0


def _brick(c: _Canvas) -> np.ndarray:
    """Stretcher-bond brick wall: per-brick colour and grain, recessed mortar, ragged edges, soot."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    palette = BRICK_PALETTES[rng.integers(len(BRICK_PALETTES))]
    bw, bh = (np.array(BRICK_PX) * s * rng.uniform(0.85, 1.15)).tolist()
    m = MORTAR_PX * s
    xs, ys = _grid(h, w)
    xw = xs + 1.3 * s * _fbm(rng, h, w, 5 * s, 3) + rng.uniform(0, bw)
    yw = ys + 1.3 * s * _fbm(rng, h, w, 5 * s, 3) + rng.uniform(0, bh)
    row = np.floor(yw / bh)
    shift = (row % 2) * (bw / 2)
    col = np.floor((xw + shift) / bw)
    lx, ly = xw + shift - col * bw, yw - row * bh
    inside = np.minimum(np.minimum(lx, bw - lx), np.minimum(ly, bh - ly)) - m / 2
    mask = _smoothstep(0.0, 1.5 * s, inside)
    ncol = int(col.max()) + 2
    ids = (row.astype(np.int32) * ncol + col.astype(np.int32))
    tones = _pick(rng, palette, int(ids.max()) + 1, spread=0.07)
    grain = _fbm(rng, h, w, 6 * s, 3)
    specks = rng.random((h, w), dtype=np.float32) > 0.985
    brick = tones[ids] * (1 + 0.08 * grain - 0.25 * specks)[..., None]
    mortar = np.asarray(MORTAR_RGB, np.float32) * (1 + 0.07 * _fbm(rng, h, w, 2 * s, 3))[..., None]
    height = 3.0 * s * (mask + 0.1 * grain * mask)
    img = _lerp(mortar, brick, mask) * _shade(height, 1.0)[..., None]
    soot = _smoothstep(-0.5, 2.0, _fbm(rng, h, w, 200 * s, 4))
    img *= (1 - 0.3 * soot)[..., None]
    return _sprinkle(rng, img, 2.0)


# ---------------------------------------------------------------------------------------------------------------------
# Gravel
# ---------------------------------------------------------------------------------------------------------------------

GRAVEL_STONES: tuple[Rgb, ...] = (
    (132, 130, 126), (162, 157, 150), (100, 98, 96), (178, 164, 140), (142, 114, 90),
    (152, 108, 92), (72, 70, 68), (204, 200, 192), (118, 112, 100),
)
GRAVEL_WEIGHTS = (3, 3, 2, 2, 1, 1, 1, 1, 2)
GRAVEL_CELL_PX = 20.0
GRAVEL_GAP_RGB: Rgb = (44, 38, 32)


def _gravel(c: _Canvas) -> np.ndarray:
    """Pebbles: warped Voronoi cells shaded as domes, coloured from real river gravel, dark gaps."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    cell = GRAVEL_CELL_PX * s * rng.uniform(0.8, 1.25)
    xs, ys = _grid(h, w)
    xw = xs + 0.2 * cell * _fbm(rng, h, w, 1.5 * cell, 2)
    yw = ys + 0.2 * cell * _fbm(rng, h, w, 1.5 * cell, 2)
    f1, f2, ids, n = _voronoi(rng, xw, yw, cell)
    edge = f2 - f1
    dome = np.sqrt(np.clip(edge / (0.6 * cell), 0, 1))
    stone = _smoothstep(0.8 * s, 2.5 * s, edge)
    cols = _pick(rng, GRAVEL_STONES, n, GRAVEL_WEIGHTS, spread=0.09)
    grain = _fbm(rng, h, w, 2.0 * s, 3)
    img = cols[ids] * (1 + 0.06 * grain)[..., None]
    img = img * _shade(0.35 * cell * dome, 1.0)[..., None]
    img = _lerp(GRAVEL_GAP_RGB, img, stone)
    return _sprinkle(rng, img, 2.5)


# ---------------------------------------------------------------------------------------------------------------------
# Foliage
# ---------------------------------------------------------------------------------------------------------------------

LEAF_GREENS: tuple[Rgb, ...] = (
    (46, 92, 34), (66, 112, 42), (88, 132, 48), (112, 148, 58), (138, 160, 70), (44, 96, 64), (74, 118, 70),
)
FOLIAGE_BACKGROUND: Rgb = (16, 30, 12)
LEAF_LENGTH_PX = (24.0, 44.0)
LEAF_WIDTH_RATIO = (0.32, 0.5)
FOLIAGE_LAYERS = 3
FOLIAGE_COVER = 0.9  # leaf area per layer as a fraction of the image area
FOLIAGE_LAYER_DIM = 0.72  # each layer darkens what is behind it: depth and shadow
LEAF_OUTLINE_POINTS = 9


def _leaf_outlines(rng, n: int, h: int, w: int, s: float) -> np.ndarray:
    """n leaf outlines (n, 2 * LEAF_OUTLINE_POINTS, 2): left edge base->tip, right edge tip->base."""
    t = np.linspace(0.0, 1.0, LEAF_OUTLINE_POINTS)
    half = np.sin(np.pi * t) ** 0.8 * (1 - 0.35 * t)
    length = rng.uniform(*LEAF_LENGTH_PX, n) * s
    width = length * rng.uniform(*LEAF_WIDTH_RATIO, n) / 2
    u = np.concatenate([t, t[::-1]])[None, :] * length[:, None]
    v = np.concatenate([half, -half[::-1]])[None, :] * width[:, None]
    angle = np.pi / 2 + rng.normal(0, 0.9, n)  # leaves mostly hang down
    ca, sa = np.cos(angle)[:, None], np.sin(angle)[:, None]
    cx = rng.uniform(-0.05, 1.05, n)[:, None] * w
    cy = rng.uniform(-0.1, 1.0, n)[:, None] * h
    return np.stack([cx + u * ca - v * sa, cy + u * sa + v * ca], -1)


def _foliage(c: _Canvas) -> np.ndarray:
    """Layers of overlapping leaves, each half-leaf lit differently along its midrib, dappled light."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    img = np.empty((h, w, 3), np.float32)
    img[:] = FOLIAGE_BACKGROUND
    mean_leaf_area = 0.55 * np.mean(LEAF_LENGTH_PX) ** 2 * np.mean(LEAF_WIDTH_RATIO) * s * s
    per_layer = int(FOLIAGE_COVER * h * w / mean_leaf_area)
    k = LEAF_OUTLINE_POINTS
    for _ in range(FOLIAGE_LAYERS):
        img *= FOLIAGE_LAYER_DIM
        outlines = np.round(_leaf_outlines(rng, per_layer, h, w, s) * 16).astype(np.int32)
        cols = _pick(rng, LEAF_GREENS, per_layer, spread=0.12)
        lit = rng.uniform(0.82, 1.12, per_layer)
        for poly, col, gain in zip(outlines, cols, lit):
            cv2.fillPoly(img, [poly], (col * gain).tolist(), cv2.LINE_AA, shift=4)
            cv2.fillPoly(img, [poly[:k]], (col * gain * 0.86).tolist(), cv2.LINE_AA, shift=4)
            cv2.line(img, tuple(poly[0]), tuple(poly[k - 1]), (col * gain * 1.18).tolist(), 1, cv2.LINE_AA, shift=4)
    dapple = 0.8 + 0.35 * _smoothstep(-1.0, 1.5, _fbm(rng, h, w, 110 * s, 4))
    img *= dapple[..., None]
    return _sprinkle(rng, cv2.GaussianBlur(img, (0, 0), 0.5), 2.0)


# ---------------------------------------------------------------------------------------------------------------------
# Fur
# ---------------------------------------------------------------------------------------------------------------------

FUR_COATS: tuple[tuple[Rgb, Rgb, Rgb, float], ...] = (  # (root, tip, marking, marking strength)
    ((118, 62, 26), (236, 170, 104), (92, 42, 16), 0.8),  # ginger tabby
    ((70, 68, 66), (196, 192, 184), (30, 29, 28), 0.9),  # grey tabby
    ((66, 40, 22), (170, 118, 72), (50, 30, 16), 0.2),  # brown dog
    ((150, 140, 128), (246, 242, 232), (120, 110, 100), 0.15),  # white fluffy
    ((36, 32, 30), (120, 108, 98), (20, 18, 16), 0.3),  # dark brown / black
)
FUR_UNDERCOAT_PX = 7.0  # half-length of the short, dense strands
FUR_GUARD_PX = 20.0  # half-length of the long, sparse guard hairs
FUR_GUARD_DENSITY = 0.05  # fraction of pixels that seed a guard hair
FUR_STRIPE_PX = (60.0, 110.0)  # spacing of tabby bands
FUR_LIC_STEPS = (4, 7)  # samples per side along (undercoat, guard) strands
FUR_LIC_SUBSTEP_PX = 0.75  # sample spacing along a strand: wider spacing draws strands as dotted lines


def _lic(src: np.ndarray, xs, ys, cos_t, sin_t, half_len: float, steps: int) -> np.ndarray:
    """Line-integral convolution: average `src` along the local direction with a Hann window (strands)."""
    acc = np.zeros_like(src)
    total = 0.0
    for d in np.linspace(-half_len, half_len, 2 * steps + 1).tolist():
        weight = 0.5 + 0.5 * math.cos(math.pi * d / (half_len * 1.0001))
        acc += weight * _remap(src, xs + d * cos_t, ys + d * sin_t)
        total += weight
    return acc / total


def _strands(src: np.ndarray, xs, ys, cos_t, sin_t, half_len: float, steps: int) -> np.ndarray:
    """Two LIC passes: a short dense one fills the gaps between the long pass's samples, so long
    strands cost few remaps yet stay continuous."""
    step = half_len / steps
    fine_steps = max(math.ceil(step / FUR_LIC_SUBSTEP_PX), 1)
    dense = _lic(src, xs, ys, cos_t, sin_t, step, fine_steps)
    return _lic(dense, xs, ys, cos_t, sin_t, half_len, steps)


def _fur(c: _Canvas) -> np.ndarray:
    """Animal coat: undercoat and guard hairs drawn by line-integral convolution along a swirling flow
    field, with tabby-like markings. Every patch looks like every other: a hard case for re-acquisition."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    root, tip, mark, strength = FUR_COATS[rng.integers(len(FUR_COATS))]
    xs, ys = _grid(h, w)
    theta = rng.uniform(0, 2 * np.pi) + 0.55 * _fbm(rng, h, w, 260 * s, 3) + 0.12 * _fbm(rng, h, w, 40 * s, 2)
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    under = _strands(rng.random((h, w), dtype=np.float32), xs, ys, cos_t, sin_t, FUR_UNDERCOAT_PX * s,
                     FUR_LIC_STEPS[0])
    seeds = (rng.random((h, w), dtype=np.float32) < FUR_GUARD_DENSITY).astype(np.float32)
    jitter = 0.15 * _noise(rng, h, w, 6 * s)
    guard = _strands(seeds, xs, ys, np.cos(theta + jitter), np.sin(theta + jitter), FUR_GUARD_PX * s,
                     FUR_LIC_STEPS[1])
    clumps = _fbm(rng, h, w, 14 * s, 2)
    tone = _standardise(_standardise(under) + 0.9 * _standardise(guard) + 0.4 * clumps)
    tone = _smoothstep(-2.2, 2.2, tone)
    period = rng.uniform(*FUR_STRIPE_PX) * s
    phi = rng.uniform(0, np.pi)
    across = (xs * math.cos(phi) + ys * math.sin(phi)) / period + 0.6 * _fbm(rng, h, w, 150 * s, 4)
    bands = _lic(_smoothstep(-0.1, 0.7, np.sin(2 * np.pi * across)), xs, ys, cos_t, sin_t, FUR_GUARD_PX * s,
                 FUR_LIC_STEPS[0])  # hairy band edges; the band field is smooth, so one sparse pass will do
    markings = strength * bands * (1.2 - tone)
    img = _lerp(_lerp(root, tip, tone), mark, np.clip(markings, 0, 1))
    img *= (0.88 + 0.12 * _fbm(rng, h, w, 90 * s, 3))[..., None]
    return _sprinkle(rng, img, 1.5)


# ---------------------------------------------------------------------------------------------------------------------
# Bark
# ---------------------------------------------------------------------------------------------------------------------

BARK_COLOURS: tuple[tuple[Rgb, Rgb], ...] = (  # (ridge dark, ridge light)
    ((78, 68, 58), (132, 120, 106)),  # oak: grey-brown
    ((104, 64, 42), (166, 114, 78)),  # pine: red-brown
    ((72, 70, 66), (124, 120, 112)),  # ash: grey
)
BARK_CRACK_RGB: Rgb = (30, 24, 19)
LICHEN_RGB: Rgb = (150, 160, 128)
BARK_RIDGE_PX = 20.0  # spacing of the furrows
BARK_ELONGATION = 5.0  # ridges run this many times longer than wide
BARK_FURROW_PX = 4.0  # half-width of a furrow


def _bark(c: _Canvas) -> np.ndarray:
    """Furrowed bark: furrows along the zero-crossings of vertically stretched noise (so they meet
    and part like real bark), ridges rounded by their distance to the furrow, fibres, lichen."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    dark, light = BARK_COLOURS[rng.integers(len(BARK_COLOURS))]
    cell = BARK_RIDGE_PX * s * rng.uniform(0.8, 1.2)
    xs, ys = _grid(h, w)
    sway = 0.4 * cell * _fbm(rng, h, w, 3 * cell, 3, aspect=3.0)
    field = _remap(_fbm(rng, h, w, cell, 4, aspect=BARK_ELONGATION), xs + sway, ys)
    slope = np.hypot(cv2.Sobel(field, cv2.CV_32F, 1, 0), cv2.Sobel(field, cv2.CV_32F, 0, 1)) / 8.0
    dist = np.minimum(np.abs(field) / (slope + 1e-4), cell)  # px to the nearest furrow line
    ridge = _smoothstep(0.2 * BARK_FURROW_PX * s, 2.5 * BARK_FURROW_PX * s, dist)
    fibres = _noise(rng, h, w, 1.5 * s, aspect=10.0)
    rough = _fbm(rng, h, w, 8 * s, 3)
    height = s * (6.0 * np.sqrt(dist / cell) + 0.6 * fibres + 0.8 * rough)
    tone = _smoothstep(-2.0, 2.0, 0.8 * _fbm(rng, h, w, 40 * s, 4) + 0.5 * fibres + 0.4 * rough)
    img = _lerp(dark, light, tone)
    lichen = _smoothstep(0.9, 1.4, _fbm(rng, h, w, 60 * s, 5)) * ridge
    img = _lerp(img, LICHEN_RGB, 0.8 * lichen * (0.8 + 0.2 * rough))
    img = _lerp(BARK_CRACK_RGB, img * _shade(height, 1.0)[..., None], ridge)
    return _sprinkle(rng, img, 2.0)


# ---------------------------------------------------------------------------------------------------------------------
# Clouds / sky
# ---------------------------------------------------------------------------------------------------------------------

SKY_ZENITH: Rgb = (64, 112, 184)
SKY_HORIZON: Rgb = (168, 198, 228)
CLOUD_LIT: Rgb = (248, 248, 250)
CLOUD_SHADOW: Rgb = (150, 156, 172)
CLOUD_CELL_PX = 300.0  # size of the cloud masses
CLOUD_BILLOW_PX = 90.0  # size of the largest billows on them
CLOUD_BILLOW = 0.35  # weight of the billows (Perlin turbulence) against the masses
CLOUD_COVER = (0.2, 0.6)  # fraction of the sky under cloud
CLOUD_EDGE = 1.2  # density (std units) from a cloud's wispy rim to its opaque body
CLOUD_PUFF_PX = 12.0  # height given to one std of density when shading the billows


def _clouds(c: _Canvas) -> np.ndarray:
    """Sky with fair-weather cumulus: masses of fractal noise with billows of Perlin turbulence,
    thresholded, shaded as a height field lit from above and greyer under thick cloud.
    Deliberately low texture: the realistic hard case for a tracker."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    xs, ys = _grid(h, w)
    sky = _lerp(SKY_ZENITH, SKY_HORIZON, (ys / h) ** 1.4 * rng.uniform(0.6, 1.0))
    mass = _fbm(rng, h, w, CLOUD_CELL_PX * s, 4)
    density = _standardise(mass + CLOUD_BILLOW * _turbulence(rng, h, w, CLOUD_BILLOW_PX * s, 5))
    threshold = float(np.quantile(density, 1 - rng.uniform(*CLOUD_COVER)))
    d = _smoothstep(threshold, threshold + CLOUD_EDGE, density)
    puff = _shade(cv2.GaussianBlur(density, (0, 0), 3 * s) * CLOUD_PUFF_PX * s, 1.0)
    above = _remap(cv2.GaussianBlur(d, (0, 0), 10 * s), xs, ys - 16 * s)
    light = np.clip(0.75 + (puff - 1.0) - 0.3 * above, 0, 1)
    img = _lerp(sky, _lerp(CLOUD_SHADOW, CLOUD_LIT, light), d ** 0.7)
    return _sprinkle(rng, img, 1.0)


# ---------------------------------------------------------------------------------------------------------------------
# Granite
# ---------------------------------------------------------------------------------------------------------------------

GRANITE_STONES: tuple[tuple[tuple[Rgb, ...], tuple[int, ...]], ...] = (  # (minerals, proportions)
    (((200, 140, 128), (184, 178, 172), (34, 30, 30), (150, 100, 94), (222, 196, 186)), (40, 25, 18, 10, 7)),  # pink
    (((206, 206, 204), (150, 150, 150), (40, 40, 42), (112, 112, 114), (230, 228, 224)), (35, 28, 18, 12, 7)),  # grey
    (((22, 22, 24), (44, 44, 48), (70, 68, 66), (186, 156, 92)), (60, 25, 8, 7)),  # black galaxy
    (((150, 110, 70), (60, 50, 44), (196, 170, 132), (30, 28, 26)), (40, 25, 20, 15)),  # brown baltic
)
GRANITE_CELL_PX = (4.0, 11.0)  # small quartz/mica and large feldspar crystals


def _granite(c: _Canvas) -> np.ndarray:
    """Polished granite: angular crystals of two sizes in mineral colours, faint large-scale clouding."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    minerals, weights = GRANITE_STONES[rng.integers(len(GRANITE_STONES))]
    xs, ys = _grid(h, w)
    _, _, small_ids, n_small = _voronoi(rng, xs, ys, GRANITE_CELL_PX[0] * s)
    f1, f2, big_ids, n_big = _voronoi(rng, xs, ys, GRANITE_CELL_PX[1] * s)
    small = _pick(rng, minerals, n_small, weights, spread=0.08)[small_ids]
    big = _pick(rng, minerals[:2], n_big, weights[:2], spread=0.06)[big_ids]
    use_big = (rng.random(n_big) < 0.35)[big_ids] & (f2 - f1 > 1.0 * s)
    img = np.where(use_big[..., None], big, small)
    img *= (1 + 0.04 * _fbm(rng, h, w, 100 * s, 3))[..., None]
    return _sprinkle(rng, img, 3.0)


# ---------------------------------------------------------------------------------------------------------------------
# Sand
# ---------------------------------------------------------------------------------------------------------------------

SAND_COLOURS: tuple[tuple[Rgb, Rgb], ...] = (  # (dark, light)
    ((176, 138, 90), (232, 200, 150)),  # desert
    ((178, 166, 140), (228, 218, 196)),  # beach
    ((70, 64, 60), (128, 120, 112)),  # volcanic
)
SAND_RIPPLE_PX = (26.0, 50.0)
SAND_RIPPLE_CREST = 0.7  # fraction of the wavelength on the gentle windward slope


def _sand(c: _Canvas) -> np.ndarray:
    """Wind ripples (asymmetric, warped) lit at a low angle, over single-pixel grains of mixed colour."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    dark, light = SAND_COLOURS[rng.integers(len(SAND_COLOURS))]
    xs, ys = _grid(h, w)
    wave = rng.uniform(*SAND_RIPPLE_PX) * s
    phi = rng.uniform(0, np.pi)
    u = (xs * math.cos(phi) + ys * math.sin(phi)) / wave + 0.8 * _fbm(rng, h, w, 180 * s, 4)
    f = u - np.floor(u)
    profile = np.where(f < SAND_RIPPLE_CREST, f / SAND_RIPPLE_CREST, (1 - f) / (1 - SAND_RIPPLE_CREST))
    amplitude = rng.uniform(0.3, 1.0) * (0.6 + 0.4 * _smoothstep(-1, 1, _fbm(rng, h, w, 200 * s, 3)))
    height = cv2.GaussianBlur(profile.astype(np.float32), (0, 0), 1.2 * s) * amplitude * 4.0 * s
    grains = cv2.GaussianBlur(rng.random((h, w), dtype=np.float32), (0, 0), 0.6)
    tone = np.clip(0.5 + 0.9 * (grains - 0.5) + 0.12 * _fbm(rng, h, w, 120 * s, 4), 0, 1)
    img = _lerp(dark, light, tone) * _shade(height, 1.0)[..., None]
    return _sprinkle(rng, img, 2.0)


# ---------------------------------------------------------------------------------------------------------------------
# Printed poster
# ---------------------------------------------------------------------------------------------------------------------

POSTER_PAPERS: tuple[Rgb, ...] = ((244, 242, 236), (238, 230, 212), (30, 34, 44), (232, 70, 54), (250, 204, 60))
POSTER_INKS: tuple[Rgb, ...] = (
    (20, 20, 24), (200, 32, 44), (20, 70, 150), (0, 120, 90), (240, 140, 20), (120, 40, 120), (250, 250, 246),
)
POSTER_FONTS = (
    cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_COMPLEX, cv2.FONT_HERSHEY_TRIPLEX,
    cv2.FONT_HERSHEY_PLAIN, cv2.FONT_HERSHEY_SCRIPT_SIMPLEX, cv2.FONT_HERSHEY_COMPLEX_SMALL,
)
BODY_FONTS = POSTER_FONTS[:5]  # script fonts are unreadable at body-text size
# Layouts as (kind, x, y, w, h) in fractions of the poster; kinds: title, photo, text, block.
# Each is also used mirrored left-right.
POSTER_LAYOUTS = (
    (("title", .06, .04, .88, .16), ("photo", .06, .23, .56, .42), ("block", .66, .23, .28, .42),
     ("text", .06, .69, .42, .27), ("text", .52, .69, .42, .27)),
    (("photo", 0., 0., 1., .5), ("title", .06, .53, .88, .14), ("text", .06, .7, .27, .26),
     ("text", .37, .7, .27, .26), ("text", .68, .7, .26, .26)),
    (("block", 0., 0., .32, 1.), ("text", .03, .4, .26, .56), ("title", .36, .05, .6, .18),
     ("photo", .36, .27, .6, .36), ("text", .36, .67, .6, .29)),
    (("title", .05, .05, .9, .22), ("text", .05, .3, .4, .65), ("photo", .5, .3, .45, .3),
     ("block", .5, .63, .45, .32)),
    (("block", 0., 0., 1., .3), ("title", .05, .06, .9, .18), ("text", .05, .35, .28, .6),
     ("photo", .37, .35, .58, .38), ("text", .37, .77, .58, .2)),
    (("photo", .05, .05, .9, .62), ("title", .05, .7, .6, .12), ("block", .7, .7, .25, .25),
     ("text", .05, .84, .6, .13)),
)
POSTER_JITTER = 0.02  # of the poster size, per layout box
TEXT_LINE_PX = (9.0, 15.0)  # line height of body text
SYLLABLE_ONSETS = ("", "b", "c", "d", "f", "g", "h", "l", "m", "n", "p", "r", "s", "t", "v", "w", "st", "tr", "pl", "ch",
                   "th", "br", "sh")
SYLLABLE_VOWELS = ("a", "e", "i", "o", "u", "ea", "ou", "ai", "io")
SYLLABLE_CODAS = ("", "", "", "n", "r", "s", "t", "l", "m", "nd", "st", "rt", "ng", "ck")
SKY_PALETTES: tuple[tuple[Rgb, Rgb, Rgb, tuple[Rgb, Rgb, Rgb]], ...] = (  # (zenith, horizon, sun, ridges far->near)
    ((64, 112, 184), (214, 200, 190), (255, 240, 200), ((110, 120, 150), (70, 92, 96), (46, 70, 44))),  # day
    ((70, 60, 120), (250, 150, 90), (255, 220, 150), ((120, 80, 110), (80, 50, 80), (40, 28, 44))),  # sunset
    ((150, 190, 220), (230, 236, 240), (255, 255, 250), ((170, 180, 196), (120, 136, 150), (200, 206, 214))),  # snow
)


def _words(rng, n: int, upper: bool = False) -> str:
    """n pronounceable pseudo-words built from syllables: reads as text at a glance, in no language."""
    def word() -> str:
        k = int(rng.integers(1, 4))
        return "".join(SYLLABLE_ONSETS[rng.integers(len(SYLLABLE_ONSETS))]
                       + SYLLABLE_VOWELS[rng.integers(len(SYLLABLE_VOWELS))]
                       + SYLLABLE_CODAS[rng.integers(len(SYLLABLE_CODAS))] for _ in range(k))

    text = " ".join(word() for _ in range(n))
    return text.upper() if upper else text


def _landscape(rng, h: int, w: int) -> np.ndarray:
    """A 'photo' panel: sky gradient, sun glow, three ridge lines fading into haze, textured foreground."""
    zenith, horizon, sun_rgb, ridges = SKY_PALETTES[rng.integers(len(SKY_PALETTES))]
    xs, ys = _grid(h, w)
    img = _lerp(zenith, horizon, ys / max(h - 1, 1))
    sun = (rng.uniform(0.1, 0.9) * w, rng.uniform(0.1, 0.4) * h)
    glow = np.exp(-((xs - sun[0]) ** 2 + (ys - sun[1]) ** 2) / (0.02 * w * w + 1))
    img = _lerp(img, sun_rgb, glow)
    for k, col in enumerate(ridges):
        line = _fbm(rng, 1, w, w / 3, 5)[0] * h * 0.06 + h * (0.42 + 0.12 * k)
        img = np.where((ys > line[None, :])[..., None], np.asarray(col, np.float32), img)
    field = _fbm(rng, h, w, max(w / 40, 1.0), 3)
    img *= (1 + 0.07 * field * (ys > h * 0.6))[..., None]
    return img


def _fit_text(img, text: str, rect, font: int, colour, line_px: float, thickness: int) -> None:
    """Fill `rect` with lines of `text` at line height `line_px`, breaking at word ends."""
    x, y, rw, rh = rect
    scale = cv2.getFontScaleFromHeight(font, max(int(line_px * 0.7), 4), thickness)
    words, line, cursor = text.split(), "", y + line_px
    for word in words:
        trial = f"{line} {word}".strip()
        if cv2.getTextSize(trial, font, scale, thickness)[0][0] > rw and line:
            cv2.putText(img, line, (int(x), int(cursor)), font, scale, colour, thickness, cv2.LINE_AA)
            line, cursor = word, cursor + line_px
            if cursor > y + rh:
                return
        else:
            line = trial
    cv2.putText(img, line, (int(x), int(cursor)), font, scale, colour, thickness, cv2.LINE_AA)


def _poster_boxes(rng, h: int, w: int):
    """The boxes (kind, x, y, width, height) in px of a random layout, maybe mirrored, jittered."""
    layout = POSTER_LAYOUTS[rng.integers(len(POSTER_LAYOUTS))]
    mirror = rng.random() < 0.5
    for kind, fx, fy, fw, fh in layout:
        fx = 1 - fx - fw if mirror else fx
        jx, jy = rng.uniform(-POSTER_JITTER, POSTER_JITTER, 2) * ((fx > 0) & (fx + fw < 1), fy > 0)
        x, y = max(int((fx + jx) * w), 0), max(int((fy + jy) * h), 0)
        yield kind, x, y, max(min(int(fw * w), w - x), 8), max(min(int(fh * h), h - y), 8)


def _draw_block(rng, rw: int, rh: int, accent, paper) -> np.ndarray:
    """A colour block with a simple graphic: a disc, diagonal stripes or a triangle."""
    block = np.empty((rh, rw, 3), np.uint8)
    block[:] = accent
    side = min(rw, rh)
    shape = rng.integers(3)
    if shape == 0:
        cv2.circle(block, (rw // 2, side // 2), int(side * 0.3), paper.tolist(), -1, cv2.LINE_AA)
    elif shape == 1:
        for k in range(0, rw + rh, max(side // 5, 4)):
            cv2.line(block, (k, 0), (k - rh, rh), paper.tolist(), max(side // 14, 1), cv2.LINE_AA)
    else:
        pts = np.array([[rw // 2, side // 8], [rw // 8, side * 7 // 8], [rw * 7 // 8, side * 7 // 8]], np.int32)
        cv2.fillPoly(block, [pts], paper.tolist(), cv2.LINE_AA)
    return block


def _poster(c: _Canvas) -> np.ndarray:
    """A printed poster: a layout of title, photo panel, colour blocks and body text in Hershey fonts."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    paper = np.asarray(POSTER_PAPERS[rng.integers(len(POSTER_PAPERS))], np.float32)
    img = np.empty((h, w, 3), np.uint8)  # cv2.putText draws on 8-bit images only
    img[:] = paper
    inks = [np.asarray(i, np.float32) for i in POSTER_INKS if abs(np.mean(i) - paper.mean()) > 60]
    accent = inks[rng.integers(len(inks))]
    for kind, x, y, rw, rh in _poster_boxes(rng, h, w):
        if kind == "photo":
            img[y:y + rh, x:x + rw] = _to_uint8(_landscape(rng, rh, rw))
        elif kind == "block":
            img[y:y + rh, x:x + rw] = _draw_block(rng, rw, rh, accent, paper)
        elif kind == "title":
            font = POSTER_FONTS[rng.integers(len(POSTER_FONTS))] | (cv2.FONT_ITALIC * (rng.random() < 0.2))
            thickness = max(int(rng.integers(2, 6) * s), 1)
            text = _words(rng, int(rng.integers(1, 3)), upper=rng.random() < 0.7)
            tw, th = cv2.getTextSize(text, font, 1.0, thickness)[0]
            scale = min(rw / max(tw, 1), rh / max(th, 1) * 0.8)
            colour = accent if rng.random() < 0.5 else inks[rng.integers(len(inks))]
            cv2.putText(img, text, (x, y + int(rh * 0.8)), font, scale, colour.tolist(), thickness, cv2.LINE_AA)
        else:
            font = BODY_FONTS[rng.integers(len(BODY_FONTS))]
            line_px = rng.uniform(*TEXT_LINE_PX) * s
            dark_ground = img[y:y + rh, x:x + rw].mean() < 128
            ink = (250, 250, 246) if dark_ground else (30, 30, 34)
            _fit_text(img, _words(rng, 400), (x, y, rw, rh), font, ink, line_px, max(int(s), 1))
    paper_grain = 1 + 0.025 * _fbm(rng, h, w, 3 * s, 2)
    img = cv2.GaussianBlur(img.astype(np.float32) * paper_grain[..., None], (0, 0), 0.5 * max(s, 0.5))
    return _sprinkle(rng, img, 1.5)


# ---------------------------------------------------------------------------------------------------------------------
# Mosaic
# ---------------------------------------------------------------------------------------------------------------------

MOSAIC_STYLES: tuple[tuple[Rgb, Rgb, tuple[Rgb, ...]], ...] = (  # (ground, outline, fills)
    ((228, 214, 184), (42, 40, 38), ((172, 82, 52), (204, 152, 74), (80, 96, 122), (116, 128, 88))),  # Roman
    ((40, 128, 190), (10, 48, 96), ((232, 238, 240), (112, 184, 220), (18, 76, 140))),  # swimming pool
    ((240, 232, 210), (30, 50, 110), ((196, 60, 40), (238, 178, 40), (36, 110, 96))),  # Moorish
)
MOSAIC_TILE_PX = (11.0, 18.0)
MOSAIC_GROUND = 0.45  # fraction of tesserae in the ground colour
MOSAIC_OUTLINE = 0.07  # design-field distance (std units) to a band edge drawn as outline
GROUT_RGB: Rgb = (160, 152, 138)
MOSAIC_GROUT_PX = 1.3


def _mosaic(c: _Canvas) -> np.ndarray:
    """Tesserae in offset rows, each one glazed colour: a ground, and bands of a smooth warped design
    outlined in a dark colour, as in floor mosaics."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    ground, outline, fills = MOSAIC_STYLES[rng.integers(len(MOSAIC_STYLES))]
    tile = rng.uniform(*MOSAIC_TILE_PX) * s
    xs, ys = _grid(h, w)
    xw = xs + 0.5 * s * _fbm(rng, h, w, 4 * s, 2)
    yw = ys + 0.5 * s * _fbm(rng, h, w, 4 * s, 2)
    row = np.floor(yw / tile)
    offset = rng.uniform(0, tile, int(row.max()) + 1).astype(np.float32)[row.astype(np.int32)]
    col = np.floor((xw + offset) / tile)
    ids = row.astype(np.int32) * (int(col.max()) + 2) + col.astype(np.int32)
    lx, ly = xw + offset - col * tile, yw - row * tile
    m = (rng.uniform(0.6, 1.4, (ids.max() + 1, 4)).astype(np.float32) * MOSAIC_GROUT_PX * s)[ids]
    inside = np.minimum(np.minimum(lx - m[..., 0], tile - lx - m[..., 1]), np.minimum(ly - m[..., 2], tile - ly - m[..., 3]))
    mask = _smoothstep(0.0, 1.2 * s, inside)
    wx, wy = (40 * s * _fbm(rng, h, w, 150 * s, 3) for _ in range(2))
    design = _remap(_fbm(rng, h, w, rng.uniform(100, 220) * s, 3), xs + wx, ys + wy)
    cx = ((col + 0.5) * tile - offset).clip(0, w - 1).astype(np.int32)
    cy = ((row + 0.5) * tile).clip(0, h - 1).astype(np.int32)
    level = design[cy, cx]
    edges = np.quantile(design, np.linspace(MOSAIC_GROUND, 0.95, len(fills) + 1)[:-1])
    palette = np.asarray((ground,) + fills + (outline,), np.float32)
    index = np.searchsorted(edges, level)
    near_edge = np.abs(level[..., None] - edges).min(-1) < MOSAIC_OUTLINE
    index = np.where(near_edge, len(palette) - 1, index)
    vary = (1 + 0.07 * rng.standard_normal(ids.max() + 1)).astype(np.float32)[ids]
    tiles = palette[index] * (vary * (1 + 0.03 * _noise(rng, h, w, 3 * s)))[..., None]
    grout = np.asarray(GROUT_RGB, np.float32) * (1 + 0.06 * _noise(rng, h, w, 1.0))[..., None]
    img = _lerp(grout, tiles, mask) * _shade(2.0 * s * mask, 1.0)[..., None]
    return _sprinkle(rng, img, 2.0)


# ---------------------------------------------------------------------------------------------------------------------
# Woven fabric
# ---------------------------------------------------------------------------------------------------------------------

THREAD_PX = (4.0, 7.0)
TARTAN_COLOURS: tuple[Rgb, ...] = ((160, 28, 36), (18, 60, 40), (20, 30, 70), (220, 190, 60), (236, 234, 226),
                                   (20, 20, 22))
DENIM = ((38, 58, 108), (204, 202, 194))  # (warp indigo, weft ecru)
TWEED = (((62, 54, 48), (84, 66, 52)), ((176, 164, 142), (150, 138, 118)))  # (dark warps, light wefts)


FABRIC_HEATHER = (0.14, 0.06, 0.14)  # fibre-to-fibre brightness variation of denim, tartan, tweed yarn


def _sett(rng, n_threads: int) -> np.ndarray:
    """A mirrored tartan sett: colour index per thread, stripes 1-12 threads wide."""
    k = int(rng.integers(3, 6))
    cols = rng.choice(len(TARTAN_COLOURS), k, replace=False)
    widths = rng.integers(1, 13, k)
    half = np.repeat(cols, widths)
    unit = np.concatenate([half, half[::-1]])
    return np.resize(unit, n_threads)


def _fabric(c: _Canvas) -> np.ndarray:
    """Woven cloth (denim twill, tartan twill or herringbone tweed): threads with rounded profiles,
    fibre streaks along each thread, and slack folds."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    style = int(rng.integers(3))
    pitch = rng.uniform(*THREAD_PX) * s
    xs, ys = _grid(h, w)
    fold = _fbm(rng, h, w, 150 * s, 3)
    xw, yw = xs + 3 * s * fold, ys - 2 * s * fold
    i, j = np.floor(xw / pitch).astype(np.int32), np.floor(yw / pitch).astype(np.int32)
    u, v = xw / pitch - i, yw / pitch - j
    n_i, n_j = int(i.max()) + 2, int(j.max()) + 2
    if style == 0:  # denim: 3/1 twill, warp dominant
        warp_top = (i + j) % 4 != 0
        warp_col = np.broadcast_to(np.asarray(DENIM[0], np.float32), (n_i, 3)).copy()
        weft_col = np.broadcast_to(np.asarray(DENIM[1], np.float32), (n_j, 3)).copy()
        warp_col *= (1 + 0.12 * rng.standard_normal((n_i, 1))).astype(np.float32)  # slub yarn
    elif style == 1:  # tartan: 2/2 twill, same sett both ways
        warp_top = (i + j) % 4 < 2
        sett = _sett(rng, max(n_i, n_j))
        table = np.asarray(TARTAN_COLOURS, np.float32)
        warp_col, weft_col = table[sett[:n_i]], table[sett[:n_j]]
    else:  # herringbone tweed: twill direction flips every 8 warp threads
        zig = np.where((i // 8) % 2 == 0, i, -i)
        warp_top = (zig + j) % 4 < 2
        warp_col = _pick(rng, TWEED[0], n_i, spread=0.1)
        weft_col = _pick(rng, TWEED[1], n_j, spread=0.1)
    along = np.where(warp_top, v, u)
    across = np.where(warp_top, u, v)
    profile = np.sin(np.pi * np.clip(across, 0, 1)) ** 0.6 * (0.75 + 0.25 * np.sin(np.pi * along))
    fibre_v = _noise(rng, h, w, 1.0, aspect=6.0 * s)
    fibre_h = _noise(rng, h, w, 6.0 * s, aspect=1 / (6.0 * s))
    fibre = np.where(warp_top, fibre_v, fibre_h)
    colour = np.where(warp_top[..., None], warp_col[np.clip(i, 0, n_i - 1)], weft_col[np.clip(j, 0, n_j - 1)])
    heather = FABRIC_HEATHER[style]
    img = colour * (0.55 + 0.45 * profile + heather * fibre)[..., None]
    if style == 0:  # worn denim: indigo rubbed off in patches
        worn = 0.35 * _smoothstep(0.3, 2.0, _fbm(rng, h, w, 120 * s, 4))
        img = _lerp(img, img * 1.5 + 25.0, worn)
    img *= _shade(6.0 * s * fold, 1.0)[..., None]
    return _sprinkle(rng, img, 2.0)


# ---------------------------------------------------------------------------------------------------------------------
# Cork notice board
# ---------------------------------------------------------------------------------------------------------------------

CORK_GRANULES: tuple[Rgb, ...] = ((184, 134, 88), (162, 112, 70), (204, 158, 108), (134, 92, 56), (100, 68, 42))
CORK_WEIGHTS = (3, 3, 2, 2, 1)
CORK_GRANULE_PX = 4.0
NOTE_PAPERS: tuple[Rgb, ...] = ((252, 236, 120), (250, 182, 200), (172, 214, 242), (246, 246, 240), (200, 236, 170),
                                (255, 255, 255))
PIN_COLOURS: tuple[Rgb, ...] = ((210, 30, 40), (30, 80, 200), (30, 160, 70), (240, 200, 20), (240, 240, 240))
NOTE_PX = (70.0, 150.0)
NOTES_PER_BOARD = (4, 9)
NOTE_TILT_DEG = 12.0
NOTE_SHADOW_OFFSET_PX = 3.0
HANDWRITING_FONTS = (cv2.FONT_HERSHEY_SCRIPT_SIMPLEX, cv2.FONT_HERSHEY_SCRIPT_COMPLEX, cv2.FONT_HERSHEY_PLAIN)


def _cork(rng, h: int, w: int, s: float) -> np.ndarray:
    xs, ys = _grid(h, w)
    xw = xs + 1.5 * s * _noise(rng, h, w, 3 * s)
    yw = ys + 1.5 * s * _noise(rng, h, w, 3 * s)
    _, _, ids, n = _voronoi(rng, xw, yw, CORK_GRANULE_PX * s)
    img = _pick(rng, CORK_GRANULES, n, CORK_WEIGHTS, spread=0.1)[ids]
    pits = _smoothstep(2.3, 3.0, _noise(rng, h, w, 1.5 * s))
    img *= (1 - 0.6 * pits)[..., None]
    return img * (1 + 0.05 * _fbm(rng, h, w, 80 * s, 3))[..., None]


def _note(rng, nh: int, nw: int, s: float) -> np.ndarray:
    """One paper note: plain, lined or sticky, with a few handwritten lines."""
    paper = np.asarray(NOTE_PAPERS[rng.integers(len(NOTE_PAPERS))], np.float32)
    note = np.empty((nh, nw, 3), np.uint8)  # cv2.putText draws on 8-bit images only
    note[:] = paper
    line_px = rng.uniform(12, 18) * s
    if rng.random() < 0.4:  # ruled paper
        for y in np.arange(line_px * 1.5, nh, line_px):
            cv2.line(note, (0, int(y)), (nw - 1, int(y)), (150, 180, 220), 1, cv2.LINE_AA)
    ink = ((20, 30, 120), (20, 20, 24), (160, 20, 30))[rng.integers(3)]
    font = HANDWRITING_FONTS[rng.integers(len(HANDWRITING_FONTS))]
    margin = int(6 * s) + 1
    _fit_text(note, _words(rng, 30), (margin, margin // 2, nw - 2 * margin, nh - margin), font, ink, line_px,
              max(int(s), 1))
    curl = 1 - 0.08 * np.linspace(0, 1, nh, dtype=np.float32) ** 2  # the free end lifts off the board
    return note.astype(np.float32) * curl[:, None, None]


def _corkboard(c: _Canvas) -> np.ndarray:
    """Cork notice board (granules, pits) with pinned paper notes, their shadows and push pins."""
    rng, h, w, s = c.rng, c.h, c.w, c.s
    img = _cork(rng, h, w, s)
    for _ in range(int(rng.integers(*NOTES_PER_BOARD))):
        nw, nh = (rng.uniform(*NOTE_PX, 2) * s).astype(int) + 8
        note = _note(rng, nh, nw, s)
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        rot = cv2.getRotationMatrix2D((nw / 2, nh / 2), rng.uniform(-NOTE_TILT_DEG, NOTE_TILT_DEG), 1.0)
        rot[:, 2] += (cx - nw / 2, cy - nh / 2)
        paper = cv2.warpAffine(note, rot, (w, h), flags=cv2.INTER_LINEAR)
        mask = cv2.warpAffine(np.ones((nh, nw), np.float32), rot, (w, h), flags=cv2.INTER_LINEAR)
        drop = rot.copy()
        drop[:, 2] += NOTE_SHADOW_OFFSET_PX * s  # the shadow falls down-right, away from the lamp
        shadow = cv2.GaussianBlur(cv2.warpAffine(np.ones((nh, nw), np.float32), drop, (w, h)), (0, 0), 3 * s)
        img *= (1 - 0.45 * shadow)[..., None]
        img = img * (1 - mask[..., None]) + paper
        pin = rot @ np.array([nw / 2, 6 * s + 3, 1.0])
        pin_colour = np.asarray(PIN_COLOURS[rng.integers(len(PIN_COLOURS))], np.float32)
        centre, radius = (int(pin[0]), int(pin[1])), max(int(5 * s), 2)
        cv2.circle(img, (centre[0] + radius // 2, centre[1] + radius // 2), radius, (40, 30, 20), -1, cv2.LINE_AA)
        cv2.circle(img, centre, radius, pin_colour.tolist(), -1, cv2.LINE_AA)
        cv2.circle(img, (centre[0] - radius // 3, centre[1] - radius // 3), max(radius // 3, 1),
                   np.minimum(pin_colour + 90, 255).tolist(), -1, cv2.LINE_AA)
    return _sprinkle(rng, img, 2.0)


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
    cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    return path
