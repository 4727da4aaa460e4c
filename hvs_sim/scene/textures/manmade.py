"""Man-made surfaces: printed posters, mosaics, woven fabric and cork notice boards.

Posters and notice boards share the text helpers (made-up words, text fitted to a box); the fabric's
weaves are the ones the people's woven cloth uses (`hvs_sim/scene/noise.py`).
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.scene.noise import fbm as _fbm
from hvs_sim.scene.noise import value_noise as _noise
from hvs_sim.scene.noise import weave_over
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
    _to_uint8,
    _voronoi,
)

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
    img = cv2.GaussianBlur(img.astype(np.float32) * paper_grain[..., None], (0, 0),  # type: ignore[assignment]
                           0.5 * max(s, 0.5))  # float from here on
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
        warp_top = weave_over(j, i, "twill31")
        warp_col = np.broadcast_to(np.asarray(DENIM[0], np.float32), (n_i, 3)).copy()
        weft_col = np.broadcast_to(np.asarray(DENIM[1], np.float32), (n_j, 3)).copy()
        warp_col *= (1 + 0.12 * rng.standard_normal((n_i, 1))).astype(np.float32)  # slub yarn
    elif style == 1:  # tartan: 2/2 twill, same sett both ways
        warp_top = weave_over(j, i, "twill22")
        sett = _sett(rng, max(n_i, n_j))
        table = np.asarray(TARTAN_COLOURS, np.float32)
        warp_col, weft_col = table[sett[:n_i]], table[sett[:n_j]]
    else:  # herringbone tweed: twill direction flips every 8 warp threads
        warp_top = weave_over(j, i, "herringbone")
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
        # the shadow falls down-right, away from the lamp (rot is float64: getRotationMatrix2D)
        drop[:, 2] += NOTE_SHADOW_OFFSET_PX * s  # type: ignore[arg-type]
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
