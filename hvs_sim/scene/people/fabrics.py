"""The people's cloth, skin and hair: seeded, seamlessly tiling procedural textures.

Yarn-dyed weaves (tartan, gingham, pinstripe, denim, chambray, twill, herringbone), knits (jersey, melange,
stripes, chunky knit), prints (dots, florals) and corduroy, plus skin and hair; `fabric_texture` is the entry.
They tile because a texture wraps round a body part: the noise is `periodic_noise` (`hvs_sim/scene/noise.py`).
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.scene.noise import periodic_noise, weave_over

# ------------------------------------------------------------------------------------------------
# Procedural fabrics. Every texture tiles seamlessly: noise is filtered in the Fourier domain and
# thread/stitch/motif repeats divide the tile size.

FABRIC_KINDS = (
    "stripes", "pinstripe", "tartan", "gingham", "denim", "chambray", "twill", "herringbone",
    "corduroy", "knit", "jersey", "melange", "dots", "floral", "plain_weave",
)
THREAD_PX = 4  # texels per yarn in woven fabrics
YARN_SLUB = 0.05  # per-yarn brightness spread: what makes a weave look woven rather than printed
DYE_VARIATION = 0.035  # low-frequency unevenness of dye and wear
GRAIN = 0.02  # texel-level fibre noise
# HERRINGBONE_BAND, periodic_noise and the weaves (which yarn lies on top) are in hvs_sim/scene/noise.py,
# shared with the wall's woven fabric.


def woven(rng: np.random.Generator, size: int, warp: np.ndarray, weft: np.ndarray, weave: str,
          thread_px: int = THREAD_PX, slub_stretch: float = 1.0) -> np.ndarray:
    """Float RGB image of a woven cloth from per-yarn colours (yarn-dyed: checks and tartans).

    warp: (n, 3) colour of each vertical yarn, weft: (n, 3) of each horizontal one, n = size / thread_px.
    Each yarn is shaded as a cylinder that dips where it passes under a crossing yarn.
    """
    n, t = size // thread_px, thread_px
    over = weave_over(*np.mgrid[0:n, 0:n], weave)  # type: ignore[call-arg]  # rows are weft yarns (mgrid: two arrays)
    warp_gain = 1.0 + YARN_SLUB * rng.standard_normal(n)
    weft_gain = 1.0 + YARN_SLUB * rng.standard_normal(n)
    slub = 1.0 + 0.5 * YARN_SLUB * periodic_noise(rng, (size, size), 2.0 * t, slub_stretch)
    # one crossing, seen with the warp on top: bright along the yarn's middle, darker where it dives
    f = np.sin(np.pi * (np.arange(t) + 0.5) / t)
    warp_cell = np.outer(0.88 + 0.12 * f, 0.7 + 0.3 * f)
    shade = np.where(over[:, None, :, None], warp_cell[None, :, None, :], warp_cell.T[None, :, None, :])
    over_px = np.repeat(np.repeat(over, t, axis=0), t, axis=1)
    gain = shade.reshape(size, size) * np.where(over_px, slub, slub.T)
    warp_rgb, weft_rgb = warp * warp_gain[:, None], weft * weft_gain[:, None]
    cell_rgb = np.where(over[..., None], warp_rgb[None, :, :], weft_rgb[:, None, :])
    return np.repeat(np.repeat(cell_rgb, t, axis=0), t, axis=1) * gain[..., None]


def knitted(rng: np.random.Generator, size: int, course_rgb: np.ndarray, stitch: tuple[int, int]) -> np.ndarray:
    """Float RGB image of a weft knit: columns of V-shaped stitches; course_rgb (rows, 3) per stitch row.

    The stitch width and height must divide `size` (texture sizes are multiples of 16).
    """
    sw, sh = stitch
    y, x = np.mgrid[0:size, 0:size]
    fy, fx = (y % sh + 0.5) / sh, (x % sw + 0.5) / sw
    # the two legs of a stitch lean towards the wale centre and meet at the bottom of the V
    dist = np.minimum(np.abs(fx - (0.06 + 0.36 * fy)), np.abs(fx - (0.94 - 0.36 * fy)))
    leg = np.clip(1.0 - dist / 0.24, 0.0, 1.0)
    shade = 0.6 + 0.4 * np.sin(0.5 * np.pi * leg) * (0.85 + 0.15 * np.sin(np.pi * fy))
    stitch_gain = 1.0 + 0.6 * YARN_SLUB * rng.standard_normal((size // sh, size // sw))
    colour = course_rgb[y // sh] * stitch_gain[y // sh, x // sw][..., None]
    return colour * shade[..., None]


def _fine_weave_shade(rng: np.random.Generator, size: int) -> np.ndarray:
    """Plain-weave luminance for printed cloth: the print sits on a visible but soft thread grid."""
    grey = np.ones((size // THREAD_PX, 3))
    return woven(rng, size, grey, grey, "plain")[..., 0]


def _bands(rng: np.random.Generator, n: int, n_colours: int, min_width: int, max_width: int) -> np.ndarray:
    """Colour index per yarn for a mirrored sett (tartans are symmetric about pivots) of n yarns."""
    half: list[int] = []
    while len(half) < n // 2:
        half += [int(rng.integers(n_colours))] * int(rng.integers(min_width, max_width + 1))
    sett = np.array(half[: n // 2])
    return np.concatenate([sett, sett[::-1]])


def _stripe_sett(n: int, widths: tuple[int, ...]) -> np.ndarray:
    """Colour index per yarn/course for stripes that repeat every sum(widths) yarns (must divide n)."""
    one = np.concatenate([np.full(w, k) for k, w in enumerate(widths)])
    return np.tile(one, n // len(one) + 1)[:n]


def _divisor_near(n: int, target: float) -> int:
    """Divisor of n closest to target, so a repeat tiles the texture exactly."""
    divs = [d for d in range(1, n + 1) if n % d == 0]
    return min(divs, key=lambda d: abs(d - target))


def _tartan(rng, size, c):
    n = size // THREAD_PX
    sett = _bands(rng, n, len(c), 2, 14)
    return woven(rng, size, c[sett], c[sett], "twill22")


def _gingham(rng, size, c):
    n = size // THREAD_PX
    w = _divisor_near(n, rng.uniform(4, 9))
    sett = (np.arange(n) // w) % 2
    return woven(rng, size, c[sett], c[sett], "plain")


def _pinstripe(rng, size, c):
    n = size // THREAD_PX
    period = _divisor_near(n, rng.uniform(6, 16))
    warp = np.where(np.arange(n) % period < max(1, period // 6), 1, 0)
    return woven(rng, size, c[warp], c[np.zeros(n, int)], "plain")


def _stripes(rng, size, c):
    """Knitted horizontal stripes (a Breton or rugby top): stripes follow the stitch courses."""
    stitch = (8, 8)
    rows = size // stitch[1]
    period = _divisor_near(rows, rng.uniform(5, 14))
    widths = [max(1, round(period * rng.uniform(0.3, 0.6)))]
    widths.append(period - widths[0])
    if len(c) > 2 and period >= 6:  # a thin accent stripe inside the wide one
        widths = [widths[0], 1, widths[1] - 1]
    return knitted(rng, size, c[_stripe_sett(rows, tuple(widths)) % len(c)], stitch)


def _denim(rng, size, c):
    n = size // THREAD_PX
    indigo, ecru = c[0], c[1]
    img = woven(rng, size, np.tile(indigo, (n, 1)), np.tile(ecru, (n, 1)), "twill31", slub_stretch=6.0)
    fade = 1.0 + 0.06 * periodic_noise(rng, (size, size), size / 6.0, stretch=0.5)
    return img * fade[..., None]


def _chambray(rng, size, c):
    n = size // THREAD_PX
    return woven(rng, size, np.tile(c[0], (n, 1)), np.tile(c[1], (n, 1)), "plain", slub_stretch=4.0)


def _twill(rng, size, c):
    n = size // THREAD_PX
    return woven(rng, size, np.tile(c[0], (n, 1)), np.tile(c[0] * 0.85, (n, 1)), "twill22")


def _herringbone(rng, size, c):
    n = size // THREAD_PX
    return woven(rng, size, np.tile(c[0], (n, 1)), np.tile(c[1], (n, 1)), "herringbone")


def _plain_weave(rng, size, c):
    """Oxford-like cloth: coloured warp, slightly lighter weft, which gives a fine speckle."""
    n = size // THREAD_PX
    return woven(rng, size, np.tile(c[0], (n, 1)), np.tile(0.75 * c[0] + 0.25, (n, 1)), "plain", slub_stretch=3.0)


def _corduroy(rng, size, c):
    wale = _divisor_near(size, 10)
    x = np.arange(size)[None, :]
    ridge = 0.62 + 0.38 * np.sin(np.pi * (x % wale + 0.5) / wale) ** 1.5
    pile = 1.0 + 0.06 * periodic_noise(rng, (size, size), 1.5, stretch=4.0)
    return c[0] * (ridge * pile)[..., None]


def _knit(rng, size, c):
    """A chunky sweater knit in one colour."""
    stitch = (16, 16)
    return knitted(rng, size, np.tile(c[0], (size // stitch[1], 1)), stitch)


def _jersey(rng, size, c):
    """Fine T-shirt jersey."""
    stitch = (8, 8)
    return knitted(rng, size, np.tile(c[0], (size // stitch[1], 1)), stitch)


def _melange(rng, size, c):
    """Heather-grey-like jersey: fibres of a lighter and a darker shade mixed into the base."""
    img = _jersey(rng, size, c[:1])
    fibres = periodic_noise(rng, (size, size), 0.8, stretch=3.0)
    light = np.clip(fibres - 1.0, 0, None)
    dark = np.clip(-fibres - 1.0, 0, None)
    return img * (1.0 + 0.3 * light - 0.25 * dark)[..., None]


def _wrap_offsets(size: int, x: float, y: float, reach: float) -> list[tuple[int, int]]:
    """Shifts by ±size at which a motif at (x, y) reaching `reach` px must be drawn again to tile."""
    xs = [0] + [d * size for d in (-1, 1) if (x < reach if d > 0 else x > size - reach)]
    ys = [0] + [d * size for d in (-1, 1) if (y < reach if d > 0 else y > size - reach)]
    return [(ox, oy) for ox in xs for oy in ys]


def _dots(rng, size, c):
    """Small polka dots on a half-drop grid (an even number of rows, so it tiles), printed on plain weave."""
    pitch = _divisor_near(size // 2, rng.uniform(22, 40))
    radius = pitch * rng.uniform(0.12, 0.22)
    y, x = np.mgrid[0:size, 0:size].astype(np.float32) + 0.5
    dx = np.mod(x - 0.5 * pitch * (y // pitch % 2), pitch) - 0.5 * pitch
    dy = np.mod(y, pitch) - 0.5 * pitch
    dot = np.clip(radius + 0.5 - np.hypot(dx, dy), 0.0, 1.0)[..., None]  # anti-aliased edge
    img = c[0] * (1 - dot) + c[1] * dot
    return img * _fine_weave_shade(rng, size)[..., None]


def _flower(canvas: np.ndarray, centre, radius: float, angle: float, petal, middle, leaf) -> None:
    """Five elliptic petals, a leaf and a centre dot, drawn in place with wrap-around by the caller."""
    x, y = centre
    leaf_dir = angle + 0.6
    lx, ly = x + 1.3 * radius * np.cos(leaf_dir), y + 1.3 * radius * np.sin(leaf_dir)
    cv2.ellipse(canvas, (int(lx), int(ly)), (int(0.8 * radius), max(1, int(0.35 * radius))),
                np.degrees(leaf_dir), 0, 360, leaf, -1, cv2.LINE_AA)
    for k in range(5):
        a = angle + 2 * np.pi * k / 5
        px, py = x + 0.6 * radius * np.cos(a), y + 0.6 * radius * np.sin(a)
        cv2.ellipse(canvas, (int(px), int(py)), (int(0.55 * radius), max(1, int(0.35 * radius))),
                    np.degrees(a), 0, 360, petal, -1, cv2.LINE_AA)
    cv2.circle(canvas, (int(x), int(y)), max(1, int(0.28 * radius)), middle, -1, cv2.LINE_AA)


def _floral(rng, size, c):
    """A ditsy print: small flowers scattered on a jittered grid, printed on plain weave."""
    canvas = np.empty((size, size, 3), np.float32)
    canvas[:] = c[0]
    pitch = _divisor_near(size, rng.uniform(36, 56))
    radius = pitch * rng.uniform(0.22, 0.3)
    petals = [tuple(float(v) for v in c[k]) for k in (1, 2)]
    middle, leaf = tuple(float(v) for v in c[3]), tuple(float(v) for v in c[4])
    for gy in range(size // pitch):
        for gx in range(size // pitch):
            cx, cy = (np.array([gx, gy]) + 0.5 + rng.uniform(-0.25, 0.25, 2)) * pitch
            angle, petal = rng.uniform(0, 2 * np.pi), petals[int(rng.integers(2))]
            for ox, oy in _wrap_offsets(size, cx, cy, 2.2 * radius):
                _flower(canvas, (cx + ox, cy + oy), radius, angle, petal, middle, leaf)
    return canvas * _fine_weave_shade(rng, size)[..., None]


_FABRICS = {
    "stripes": (_stripes, 2), "pinstripe": (_pinstripe, 2), "tartan": (_tartan, 3), "gingham": (_gingham, 2),
    "denim": (_denim, 2), "chambray": (_chambray, 2), "twill": (_twill, 1), "herringbone": (_herringbone, 2),
    "corduroy": (_corduroy, 1), "knit": (_knit, 1), "jersey": (_jersey, 1), "melange": (_melange, 1),
    "dots": (_dots, 2), "floral": (_floral, 5), "plain_weave": (_plain_weave, 1),
}


def fabric_colours_needed(kind: str) -> int:
    """Fewest colours `fabric_texture` needs for this kind (tartan and stripes use any extra ones)."""
    if kind not in _FABRICS:
        raise choice_error("fabric", kind, FABRIC_KINDS)
    return _FABRICS[kind][1]


def _finish(rng: np.random.Generator, img: np.ndarray) -> np.ndarray:
    """Uneven dye and fibre grain over the whole cloth, then 8-bit RGB."""
    size = img.shape[0]
    dye = 1.0 + DYE_VARIATION * periodic_noise(rng, (size, size), size / 8.0)
    grain = 1.0 + GRAIN * rng.standard_normal((size, size))
    return np.clip(img * (dye * grain)[..., None] * 255.0, 0, 255).astype(np.uint8)


def fabric_texture(kind: str, colours, seed: int, size: int = 256) -> np.ndarray:
    """Seeded, seamlessly tiling (size, size, 3) RGB uint8 texture of a fabric.

    colours: RGB triples in 0..255, at least `fabric_colours_needed(kind)` of them; their meaning
    depends on the kind (ground first, then pattern colours; denim: indigo warp, ecru weft).
    """
    if kind not in _FABRICS:
        raise choice_error("fabric", kind, FABRIC_KINDS)
    make, needed = _FABRICS[kind]
    c = np.asarray(colours, float).reshape(-1, 3) / 255.0
    if len(c) < needed:
        raise ConfigError(f"fabric {kind!r} needs at least {needed} colours, got {len(c)}")
    if not (isinstance(size, (int, np.integer)) and 64 <= size <= 2048 and size % 16 == 0):
        raise ConfigError(f"fabric texture size must be a multiple of 16 in [64, 2048], got {size!r}")
    rng = np.random.default_rng(seed)
    return _finish(rng, make(rng, size, c))


def skin_texture(rgb, seed: int, size: int = 256) -> np.ndarray:
    """Skin: the base tone with soft blotches (a little redder where darker) and fine pores."""
    rng = np.random.default_rng(seed)
    base = np.asarray(rgb, float) / 255.0
    blotch = periodic_noise(rng, (size, size), size / 12.0)
    pores = periodic_noise(rng, (size, size), 0.8)
    redness = np.array([0.025, -0.02, -0.02])  # relative: the same flush on every skin tone
    flush = 1.0 + redness * np.clip(-blotch, 0, None)[..., None]
    img = base * (1.0 + 0.035 * blotch + 0.02 * pores)[..., None] * flush
    return np.clip(img * 255.0, 0, 255).astype(np.uint8)


def hair_texture(rgb, seed: int, size: int = 256) -> np.ndarray:
    """Hair: long vertical strands of varying brightness with a soft sheen band."""
    rng = np.random.default_rng(seed)
    base = np.asarray(rgb, float) / 255.0
    strands = periodic_noise(rng, (size, size), 0.9, stretch=40.0)
    clumps = periodic_noise(rng, (size, size), 6.0, stretch=8.0)
    gain = 1.0 + 0.16 * strands + 0.1 * clumps
    return np.clip(base * gain[..., None] * 255.0 + 6.0 * np.clip(strands, 0, None)[..., None], 0, 255).astype(np.uint8)
