"""Natural materials: wood, marble, brick, gravel, foliage, fur, bark, sky, granite and sand.

Each family is one generator `_name(canvas) -> float RGB image`, with its palette (read off photographs of
the real material) and feature sizes (pixels of a 512 px image) as constants above it.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from hvs_sim.scene.noise import fbm as _fbm
from hvs_sim.scene.noise import standardise as _standardise
from hvs_sim.scene.noise import turbulence as _turbulence
from hvs_sim.scene.noise import value_noise as _noise
from hvs_sim.scene.textures.base import (
    Rgb,
    _Canvas,
    _grid,
    _lerp,
    _pick,
    _remap,
    _shade,
    _smoothstep,
    _sprinkle,
    _voronoi,
)

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
