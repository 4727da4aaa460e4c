"""People who walk in front of the target: clothed, textured bodies, or the original plain figure.

A person 0.3–0.5 m from the lens fills most of the frame, so trackers see its clothes rather than
its outline: a flat-coloured slab is far easier to tell from the target than a person in a plaid
shirt. The textured style builds a body (rounded torso, shoulders, sleeves over arms, hands, neck,
head with face and hair, trousers or a skirt, shoes) from low-poly meshes whose texture
coordinates are metres of surface, so fabrics keep their real scale, with cloth folds in the
geometry. Fabrics are procedural and seeded (numpy/OpenCV): yarn-dyed weaves (tartan, gingham,
pinstripe, denim, chambray, twill, herringbone), knits (jersey, melange, stripes, chunky knit),
prints (dots, florals) and corduroy. Textures and meshes go to MuJoCo as in-memory assets.

Render cost (640×480 `Renderer.rgb()`, hand-held walk_by seed 0, frames 60–100, Mesa llvmpipe on a
shared 2-core machine, medians of 205 interleaved renders, three runs): plain 25.3–26.2 ms, textured
27.5–28.2 ms (+5–9 %; +8–11 % on the frames where the person fills the view).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from dm_control import mjcf

from hvs_sim.errors import ConfigError, choice_error

OCCLUDER_GROUP = 3  # geom group of people, so that renders can hide them
PERSON_STYLES = ("textured", "plain")

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
HERRINGBONE_BAND = 8  # yarns between turns of a herringbone's diagonal


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


def _weave_over(n: int, weave: str) -> np.ndarray:
    """(n, n) bool: True where the warp (vertical yarn) lies on top; rows are weft yarns."""
    i, j = np.mgrid[0:n, 0:n]
    if weave == "plain":
        return (i + j) % 2 == 0
    if weave == "twill31":  # denim: warp floats over three wefts, a steep diagonal rib
        return (i + j) % 4 != 0
    if weave == "twill22":
        return (i + j) % 4 < 2
    if weave == "herringbone":  # a 2/2 twill whose diagonal turns every HERRINGBONE_BAND yarns
        flip = (j // HERRINGBONE_BAND) % 2 == 1
        return np.where(flip, (i - j) % 4 < 2, (i + j) % 4 < 2)
    raise choice_error("weave", weave, ("plain", "twill31", "twill22", "herringbone"))


def woven(rng: np.random.Generator, size: int, warp: np.ndarray, weft: np.ndarray, weave: str,
          thread_px: int = THREAD_PX, slub_stretch: float = 1.0) -> np.ndarray:
    """Float RGB image of a woven cloth from per-yarn colours (yarn-dyed: checks and tartans).

    warp: (n, 3) colour of each vertical yarn, weft: (n, 3) of each horizontal one, n = size / thread_px.
    Each yarn is shaded as a cylinder that dips where it passes under a crossing yarn.
    """
    n, t = size // thread_px, thread_px
    over = _weave_over(n, weave)
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
    half = []
    while len(half) < n // 2:
        half += [int(rng.integers(n_colours))] * int(rng.integers(min_width, max_width + 1))
    half = np.array(half[: n // 2])
    return np.concatenate([half, half[::-1]])


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


# ------------------------------------------------------------------------------------------------
# Meshes. MuJoCo's primitives are tessellated finely (a capsule is ~1800 triangles), so the body is
# built from low-poly meshes instead, merged into one geom per material: that keeps the textured
# person as cheap to render as the plain one. Texture coordinates are in metres of surface divided
# by the texture's tile size, so fabrics keep their real scale on every part.


@dataclass(frozen=True)
class MeshData:
    vertices: np.ndarray  # (v, 3)
    normals: np.ndarray  # (v, 3)
    texcoords: np.ndarray  # (v, 2)
    faces: np.ndarray  # (f, 3)


@dataclass(frozen=True)
class Tube:
    """A smooth closed tube through knots in the person's body frame; knots run top to bottom.

    Cross-sections are superellipses (`squareness` 2 = ellipse, larger = boxier) with half extent
    `half_a` along `forward` (made perpendicular to the tube) and `half_b` across it. Each end is
    "round" (closed by a half-ellipsoid, as at a shoulder) or "flat" (a hem).
    """

    knots: tuple  # ((x, y, z), ...)
    half_a: tuple
    half_b: tuple
    squareness: float = 2.0
    start: str = "round"
    end: str = "flat"
    forward: tuple = (1.0, 0.0, 0.0)


CAP_RINGS = 4  # rings in a rounded tube end
ROUND_END_DEPTH = 0.8  # a rounded end bulges this fraction of its radius past the last knot
FOLD_WAVES = 5  # standing waves summed into a cloth wrinkle field


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _hermite(knot_s: np.ndarray, values, s: np.ndarray) -> np.ndarray:
    """Smooth (C1) interpolation through knots with finite-difference slopes: no kinks in outlines."""
    values = np.asarray(values, float)
    slopes = np.gradient(values, knot_s, axis=0)
    k = np.clip(np.searchsorted(knot_s, s, side="right") - 1, 0, len(knot_s) - 2)
    shape = (-1,) + (1,) * (values.ndim - 1)
    h = (knot_s[k + 1] - knot_s[k]).reshape(shape)
    t = ((s - knot_s[k]) / (knot_s[k + 1] - knot_s[k])).reshape(shape)
    return ((2 * t ** 3 - 3 * t ** 2 + 1) * values[k] + (t ** 3 - 2 * t ** 2 + t) * h * slopes[k]
            + (-2 * t ** 3 + 3 * t ** 2) * values[k + 1] + (t ** 3 - t ** 2) * h * slopes[k + 1])


def _superellipse(theta: np.ndarray, p: float) -> tuple[np.ndarray, np.ndarray]:
    c, s = np.cos(theta), np.sin(theta)
    return np.sign(c) * np.abs(c) ** (2.0 / p), np.sign(s) * np.abs(s) ** (2.0 / p)


def _rings(tube: Tube, n_along: int, cap_rings: int):
    """Per ring: centre, axis_a, axis_b, a, b, radial scale and cap normal, caps included; plus the
    index of the first side ring. cap_normal is zero except where a cap, not the surface, sets it."""
    knots = np.asarray(tube.knots, float)
    knot_s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(knots, axis=0), axis=1))])
    s = np.linspace(0.0, knot_s[-1], n_along)
    centre = _hermite(knot_s, knots, s)
    a, b = _hermite(knot_s, tube.half_a, s), _hermite(knot_s, tube.half_b, s)
    tangent = _unit(np.gradient(centre, axis=0))
    forward = np.asarray(tube.forward, float)
    axis_a = _unit(forward - (tangent @ forward)[:, None] * tangent)
    axis_b = np.cross(tangent, axis_a)
    rows = [(centre[i], axis_a[i], axis_b[i], a[i], b[i], 1.0, np.zeros(3)) for i in range(n_along)]
    start = _cap(rows[0], -tangent[0], tube.start, cap_rings)
    end = _cap(rows[-1], tangent[-1], tube.end, cap_rings)
    return [np.array(col) for col in zip(*(start[::-1] + rows + end))] + [len(start)]


def _cap(row, outward: np.ndarray, kind: str, cap_rings: int) -> list:
    """Rings that close a tube end: a half-ellipsoid ("round") or a flat disc ("flat")."""
    centre, axis_a, axis_b, a, b = row[:5]
    if kind == "flat":  # the rim again with the disc's normal, then the centre point
        return [(centre, axis_a, axis_b, a, b, 1.0, outward), (centre, axis_a, axis_b, a, b, 0.0, outward)]
    if kind != "round":
        raise choice_error("tube end", kind, ("round", "flat"))
    depth = ROUND_END_DEPTH * min(a, b)
    rows = []
    for k in range(1, cap_rings + 1):
        phi = 0.5 * np.pi * k / cap_rings
        pole = outward if k == cap_rings else np.zeros(3)
        rows.append((centre + outward * depth * np.sin(phi), axis_a, axis_b, a, b, np.cos(phi), pole))
    return rows


def tube_mesh(tube: Tube, tile_m: float, n_around: int, n_along: int, folds: np.ndarray | None = None,
              cap_rings: int = CAP_RINGS) -> MeshData:
    """Triangle mesh of a tube with outward normals and texture coordinates in tiles.

    folds: optional (n_along, n_around + 1) radial gains on the side rings (cloth wrinkles).
    The texture seam runs down the back (−forward side), like a garment's back seam.
    """
    centre, axis_a, axis_b, a, b, scale, cap_normal, first = _rings(tube, n_along, cap_rings)
    m = len(centre)
    theta = np.pi + 2.0 * np.pi * np.arange(n_around + 1) / n_around
    ca, sb = _superellipse(theta, tube.squareness)
    gain = np.ones((m, n_around + 1))
    if folds is not None:  # caps follow the wrinkles of the ring they close, so the ends stay sealed
        gain[:first], gain[first: first + n_along], gain[first + n_along:] = folds[0], folds, folds[-1]
    radial = ((a * scale)[:, None, None] * ca[None, :, None] * axis_a[:, None, :]
              + (b * scale)[:, None, None] * sb[None, :, None] * axis_b[:, None, :])
    points = centre[:, None, :] + gain[..., None] * radial
    normals = _grid_normals(points, centre, cap_normal)
    u = np.concatenate([np.zeros((m, 1)), np.cumsum(np.linalg.norm(np.diff(points, axis=1), axis=2), axis=1)], axis=1)
    # down the tube v follows the centre line, so horizontal stripes stay level; over the caps it
    # follows the surface
    step = np.linalg.norm(np.diff(points, axis=0), axis=2)
    side = slice(first, first + n_along - 1)
    step[side] = np.linalg.norm(np.diff(centre, axis=0), axis=1)[side, None]
    v = np.concatenate([np.zeros((1, n_around + 1)), np.cumsum(step, axis=0)])
    return _mesh(points, normals, np.stack([u, v], axis=-1) / tile_m)


def ellipsoid_mesh(centre, size, tile_m: float, n_around: int, n_lat: int) -> MeshData:
    """Low-poly axis-aligned ellipsoid (latitude-longitude grid, seam at the back)."""
    size = np.asarray(size, float)
    lat = np.linspace(0.5 * np.pi, -0.5 * np.pi, n_lat + 1)[:, None]
    lon = np.pi + 2.0 * np.pi * np.arange(n_around + 1)[None, :] / n_around
    unit = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat) * np.ones_like(lon)], axis=-1)
    points = np.asarray(centre, float) + unit * size
    normals = _unit(unit / size)
    u = (lon - np.pi) * 0.5 * (size[0] + size[1]) * np.ones_like(lat)
    v = (0.5 * np.pi - lat) * size[2] * np.ones_like(lon)
    return _mesh(points, normals, np.stack([u, v], axis=-1) / tile_m)


def merge_meshes(meshes: list[MeshData]) -> MeshData:
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return MeshData(np.concatenate([m.vertices for m in meshes]), np.concatenate([m.normals for m in meshes]),
                    np.concatenate([m.texcoords for m in meshes]),
                    np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]))


def _mesh(points: np.ndarray, normals: np.ndarray, uv: np.ndarray) -> MeshData:
    """MeshData of a (rows, cols) vertex grid, faces wound counter-clockwise seen from outside
    (MuJoCo culls back faces), degenerate triangles at poles dropped."""
    rows, cols = points.shape[:2]
    i, j = np.mgrid[0: rows - 1, 0: cols - 1]
    v00 = (i * cols + j).ravel()
    v01, v10 = v00 + 1, v00 + cols
    faces = np.concatenate([np.stack([v00, v10, v10 + 1], 1), np.stack([v00, v10 + 1, v01], 1)])
    verts, normals = points.reshape(-1, 3), normals.reshape(-1, 3)
    p0, p1, p2 = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    face_n = np.cross(p1 - p0, p2 - p0)
    keep = np.linalg.norm(face_n, axis=1) > 1e-12
    if np.sum(face_n * normals[faces].sum(axis=1), axis=1)[keep].sum() < 0:
        faces = faces[:, ::-1]
    return MeshData(verts, normals, uv.reshape(-1, 2), faces[keep])


def _grid_normals(points: np.ndarray, centre: np.ndarray, cap_normal: np.ndarray) -> np.ndarray:
    """Vertex normals of a (rings, columns) grid whose last column repeats the first (the seam)."""
    body = points[:, :-1]
    d_around = np.roll(body, -1, axis=1) - np.roll(body, 1, axis=1)
    n = np.cross(np.gradient(body, axis=0), d_around)
    if np.sum(n * (body - centre[:, None, :])) < 0:
        n = -n
    n = _unit(n)
    capped = np.any(cap_normal != 0, axis=1)
    n[capped] = cap_normal[capped][:, None, :]
    return np.concatenate([n, n[:, :1]], axis=1)


def fold_gains(rng: np.random.Generator, n_along: int, n_around: int, amplitude: float,
               around: tuple[int, int], along: tuple[float, float], envelope: np.ndarray) -> np.ndarray:
    """(n_along, n_around + 1) radial gains 1 ± amplitude: a few random standing waves of cloth.

    around: whole waves round the tube (integers keep the seam closed); along: waves down its
    length; envelope (n_along,) in [0, 1] says where the cloth bunches (elbows, knees, hems).
    """
    s = np.linspace(0.0, 1.0, n_along)[:, None]
    theta = 2.0 * np.pi * np.arange(n_around + 1)[None, :] / n_around
    field = np.zeros((n_along, n_around + 1))
    for _ in range(FOLD_WAVES):
        k = int(rng.integers(around[0], around[1] + 1))
        f = rng.uniform(*along)
        ph = rng.uniform(0, 2 * np.pi, 2)
        field += rng.uniform(0.5, 1.0) * np.sin(k * theta + ph[0]) * np.cos(2 * np.pi * f * s + ph[1])
    field /= max(np.abs(field).max(), 1e-9)
    return 1.0 + amplitude * np.asarray(envelope, float)[:, None] * field


def _bump(n: int, centre: float, width: float) -> np.ndarray:
    """Gaussian envelope over a tube's length (0 = top, 1 = bottom)."""
    return np.exp(-0.5 * ((np.linspace(0.0, 1.0, n) - centre) / width) ** 2)


# ------------------------------------------------------------------------------------------------
# Outfits: what a person wears, drawn from a private generator. Colours are sRGB 0..255.

RGB = tuple[int, int, int]
GARMENT_COLOURS: dict[str, RGB] = {
    "navy": (32, 42, 72), "black": (26, 26, 29), "charcoal": (62, 64, 68), "grey": (128, 130, 133),
    "white": (236, 236, 231), "cream": (228, 219, 196), "light_blue": (160, 188, 218), "sky": (112, 154, 205),
    "red": (168, 32, 42), "burgundy": (108, 28, 42), "olive": (98, 102, 58), "forest": (38, 78, 52),
    "khaki": (188, 168, 120), "tan": (168, 128, 84), "brown": (98, 68, 44), "mustard": (204, 158, 42),
    "orange": (214, 108, 42), "pink": (228, 160, 172), "rose": (196, 88, 110), "teal": (30, 116, 122),
    "purple": (88, 60, 118), "lavender": (172, 158, 206), "yellow": (232, 206, 88), "green": (78, 146, 82),
}
LIGHT = ("white", "cream", "light_blue", "pink", "lavender", "yellow")
DARK = ("navy", "black", "charcoal", "burgundy", "forest", "brown", "purple", "teal")
CHINO = ("khaki", "navy", "olive", "grey", "black", "tan", "charcoal", "cream", "brown")
INDIGO: tuple[RGB, ...] = ((26, 38, 72), (40, 58, 100), (74, 100, 142), (104, 132, 170), (36, 36, 40))
ECRU: RGB = (212, 204, 186)
MELANGE: tuple[RGB, ...] = ((150, 152, 155), (98, 100, 104), (196, 190, 178), (112, 124, 146), (60, 62, 66))
# skin tones from very light to deep, as sRGB under neutral light
SKIN_TONES: tuple[RGB, ...] = (
    (241, 212, 192), (230, 188, 162), (214, 166, 132), (196, 142, 106), (178, 132, 96),
    (158, 108, 74), (124, 82, 56), (96, 62, 42), (70, 46, 34),
)
HAIR_COLOURS: tuple[RGB, ...] = (
    (20, 18, 18), (44, 32, 24), (78, 54, 36), (120, 88, 58), (184, 152, 104), (116, 54, 30), (150, 148, 146),
)
TOPS = {  # kind: (fabrics, sleeve, hem height m, ease m added to the torso, fold amplitude)
    "tshirt": (("stripes", "jersey", "melange", "dots", "floral"), "short", 0.955, 0.004, 0.02),
    "shirt": (("gingham", "tartan", "pinstripe", "plain_weave", "chambray", "floral"), "long", 0.93, 0.006, 0.018),
    "jacket": (("denim", "tartan", "herringbone", "corduroy", "twill"), "long", 0.90, 0.010, 0.012),
    "hoodie": (("melange", "jersey"), "long", 0.93, 0.009, 0.02),
    "sweater": (("knit", "stripes"), "long", 0.95, 0.007, 0.015),
}
BOTTOMS = {
    "jeans": ("denim",),
    "trousers": ("twill", "herringbone", "corduroy", "tartan"),
    "skirt": ("tartan", "denim", "dots", "floral", "plain_weave", "gingham"),
}
HAIR_STYLES = ("short", "long", "bun", "buzz")
SHOES = ("sneaker", "leather")
# Fabrics are drawn at 0.3 mm per texel (4-texel yarns are 1.2 mm) and area-averaged to half that
# resolution for MuJoCo: 0.6 mm texels are about one pixel at 0.4 m, so a close person's textures are
# sampled magnified, which costs the software renderer less than minified (trilinear) sampling.
DRAW_TEXELS, TEXTURE_TEXELS = 512, 256
TILE_M = DRAW_TEXELS * 0.0003  # 0.154 m of cloth per texture tile


@dataclass(frozen=True)
class Fabric:
    """A cloth: its kind (FABRIC_KINDS), colours as `fabric_texture` reads them, and its texture's seed."""

    kind: str
    colours: tuple[RGB, ...]
    seed: int

    tile_m = TILE_M  # metres of cloth one texture tile covers

    def texture(self) -> np.ndarray:
        """TEXTURE_TEXELS² RGB uint8 tile, drawn at DRAW_TEXELS² and area-averaged (anti-aliased yarns)."""
        img = fabric_texture(self.kind, self.colours, self.seed, DRAW_TEXELS)
        return cv2.resize(img, (TEXTURE_TEXELS, TEXTURE_TEXELS), interpolation=cv2.INTER_AREA)


@dataclass(frozen=True)
class Outfit:
    """Everything that makes one person look different from another."""

    top: str
    top_fabric: Fabric
    bottom: str
    bottom_fabric: Fabric
    skin: RGB
    hair_style: str
    hair: RGB
    shoes: str
    shoe_colour: RGB
    sole_colour: RGB
    girth: float  # scales the width of the torso and the legs (not the depth: HALF_DEPTH stays true)
    skirt_hem: float  # height of a skirt's hem (m)

    @staticmethod
    def sample(rng: np.random.Generator) -> Outfit:
        """A random outfit; every draw comes from `rng`, so the same generator state gives the same person."""
        top = _pick(rng, tuple(TOPS))
        bottom = _pick(rng, tuple(BOTTOMS))
        top_kind = _pick(rng, TOPS[top][0])
        bottom_kind = _pick(rng, BOTTOMS[bottom])
        if bottom_kind == top_kind == "denim":  # no double denim: the jacket goes tartan
            top_kind = "tartan"
        shoes = _pick(rng, SHOES)
        sneaker = shoes == "sneaker"
        return Outfit(
            top=top, top_fabric=_fabric(rng, top_kind), bottom=bottom, bottom_fabric=_fabric(rng, bottom_kind),
            skin=_jitter(rng, _pick(rng, SKIN_TONES), 0.04),
            hair_style=_pick(rng, HAIR_STYLES), hair=_jitter(rng, _pick(rng, HAIR_COLOURS), 0.08),
            shoes=shoes,
            shoe_colour=_colour(rng, ("white", "black", "grey", "navy", "red") if sneaker else ("black", "brown")),
            sole_colour=_colour(rng, ("white", "cream") if sneaker else ("black", "brown")),
            girth=float(rng.uniform(0.95, 1.02)), skirt_hem=float(rng.uniform(0.5, 0.64)),
        )


def _pick(rng: np.random.Generator, options: tuple):
    return options[int(rng.integers(len(options)))]


def _jitter(rng: np.random.Generator, rgb: RGB, spread: float) -> RGB:
    return tuple(int(np.clip(round(c * rng.uniform(1 - spread, 1 + spread)), 0, 255)) for c in rgb)


def _colour(rng: np.random.Generator, names: tuple[str, ...] = tuple(GARMENT_COLOURS), spread: float = 0.06) -> RGB:
    return _jitter(rng, GARMENT_COLOURS[_pick(rng, names)], spread)


def _distinct(rng: np.random.Generator, k: int, names: tuple[str, ...] = tuple(GARMENT_COLOURS)) -> tuple[RGB, ...]:
    chosen = rng.choice(len(names), size=k, replace=False)
    return tuple(_jitter(rng, GARMENT_COLOURS[names[i]], 0.05) for i in chosen)


def _fabric(rng: np.random.Generator, kind: str) -> Fabric:
    """A fabric of the given kind in colours that such cloth is usually made in."""
    if kind == "denim":
        colours = (_jitter(rng, _pick(rng, INDIGO), 0.06), _jitter(rng, ECRU, 0.04))
    elif kind == "chambray":
        colours = (_jitter(rng, INDIGO[3], 0.08), GARMENT_COLOURS["white"])
    elif kind == "melange":
        colours = (_jitter(rng, _pick(rng, MELANGE), 0.04),)
    elif kind in ("gingham", "pinstripe", "dots", "stripes"):
        light, dark = _colour(rng, LIGHT), _colour(rng, DARK + ("red", "sky", "green", "rose"))
        ground_first = kind in ("gingham", "pinstripe") or rng.uniform() < 0.6
        colours = (light, dark) if ground_first else (dark, light)
        if kind == "stripes" and rng.uniform() < 0.4:  # an accent stripe
            colours += (_colour(rng, ("red", "mustard", "sky", "green")),)
    elif kind == "tartan":
        colours = _distinct(rng, int(rng.integers(3, 5)),
                            ("red", "navy", "forest", "black", "yellow", "white", "burgundy", "sky", "green", "grey"))
    elif kind == "herringbone":
        pair = _pick(rng, (("charcoal", "grey"), ("brown", "khaki"), ("navy", "sky"), ("black", "white")))
        colours = tuple(_jitter(rng, GARMENT_COLOURS[c], 0.05) for c in pair)
    elif kind == "floral":
        ground = _colour(rng, LIGHT + ("navy", "black"))
        petals = _distinct(rng, 2, ("red", "rose", "sky", "lavender", "orange", "pink"))
        middle, leaf = _colour(rng, ("yellow", "white", "mustard")), _colour(rng, ("green", "forest", "olive"))
        colours = (ground, *petals, middle, leaf)
    elif kind in ("twill", "corduroy"):
        colours = (_colour(rng, CHINO + (("burgundy", "mustard") if kind == "corduroy" else ())),)
    else:  # knit, jersey, plain_weave
        colours = (_colour(rng),)
    return Fabric(kind, colours, int(rng.integers(2 ** 31)))


# ------------------------------------------------------------------------------------------------
# Body geometry, metres in the person's frame: origin on the floor between the feet, +X forward,
# +Y to the left, +Z up; 1.8 m tall with hair. Arms and legs are given for the left side and mirrored.

# clothed torso from the neckline down: (z, x of the centre line, half depth, half width)
TORSO_PROFILE = (
    (1.515, -0.010, 0.050, 0.062),  # neckline
    (1.500, -0.012, 0.062, 0.100),  # base of the neck
    (1.475, -0.012, 0.074, 0.152),  # slope of the shoulders
    (1.440, -0.008, 0.086, 0.186),  # shoulder line
    (1.380, -0.002, 0.098, 0.180),  # armpits
    (1.300, 0.004, 0.104, 0.172),  # chest: with a jacket's ease its front is at HALF_DEPTH
    (1.200, 0.002, 0.098, 0.160),  # ribs
    (1.100, 0.000, 0.092, 0.152),  # waist
    (1.000, -0.004, 0.096, 0.160),  # hips
)
HEM_FLARE = 0.004  # a hem stands a little off the body
TORSO_SQUARENESS = 2.6  # between an ellipse and a rounded box: a chest seen from above
PELVIS = ((1.05, 0.000, 0.090, 0.148), (0.97, -0.004, 0.096, 0.158), (0.89, -0.008, 0.096, 0.158),
          (0.83, -0.004, 0.078, 0.122))
SKIRT = ((1.05, 0.000, 0.090, 0.148), (0.97, -0.004, 0.098, 0.162), (0.85, -0.004, 0.104, 0.180))
SKIRT_HEM_SIZE = (0.108, 0.205)
# shoulder, upper arm, elbow, forearm, wrist: hanging a little away from the body, so that the sleeves'
# outer edges at the target's height (~1.3 m) are at HALF_WIDTH, as the occlusion planning assumes
ARM_KNOTS = ((0.000, 0.205, 1.405), (-0.012, 0.228, 1.300), (-0.022, 0.224, 1.165), (0.000, 0.228, 1.030),
             (0.032, 0.232, 0.905))
SLEEVE_RADII = (0.054, 0.049, 0.045, 0.043, 0.039)
ARM_RADII = (0.046, 0.041, 0.036, 0.035, 0.028)
ARM_FLATTEN = 0.93  # arms and sleeves are a little narrower side to side than front to back
SHORT_SLEEVE = 0.4  # a T-shirt sleeve ends this far from the upper-arm knot towards the elbow
SHORT_SLEEVE_RADII = (0.056, 0.054, 0.053)
LEG_KNOTS = ((0.000, 0.088, 0.930), (0.004, 0.090, 0.720), (0.010, 0.092, 0.500), (0.002, 0.094, 0.320),
             (-0.004, 0.095, 0.060))  # hip, thigh, knee, calf, ankle (the hem covers the top of the shoe)
TROUSER_RADII = (0.086, 0.072, 0.058, 0.058, 0.055)
JEANS_RADII = (0.084, 0.068, 0.053, 0.052, 0.048)
BARE_LEG_RADII = (0.076, 0.062, 0.047, 0.052, 0.034)
NECK = ((0.0, 0.0, 1.47), (0.012, 0.0, 1.60), 0.05)  # from, to, radius
HEAD_CENTRE, HEAD_SIZE = np.array([0.012, 0.0, 1.672]), np.array([0.096, 0.077, 0.112])
HAIR_PIECES = (((0.0, 0.0, 1.725), (0.102, 0.084, 0.075)),  # crown: its front edge is the hairline, above the brows
               ((-0.03, 0.0, 1.68), (0.088, 0.084, 0.095)))  # back of the head, down to the nape
HAIR_BUZZ_SCALE = 0.975  # a buzz cut hugs the head
# shoe upper (heel, ball, toe) knots with (vertical, lateral) half sizes, and the sole from heel to toe
SHOE_UPPER = (((-0.07, 0.05), (0.042, 0.037)), ((0.02, 0.047), (0.04, 0.044)), ((0.105, 0.034), (0.026, 0.04)))
SOLE = ((-0.095, 0.14), 0.011, 0.047)  # (x from, x to), half thickness, half width
COLLARS = {  # (x, z, half depth, half width) at the top and the bottom of the collar band
    "shirt": ((-0.02, 1.57, 0.056, 0.061), (-0.01, 1.505, 0.064, 0.074)),
    "jacket": ((-0.016, 1.56, 0.06, 0.066), (-0.01, 1.5, 0.068, 0.08)),
}
CREW_NECK = ((-0.01, 1.535, 0.056, 0.062), (-0.01, 1.505, 0.06, 0.068))
BUTTON_PITCH, BUTTON_SIZE = 0.085, (0.0025, 0.006, 0.006)
ZIP_RADIUS, CORD_RADIUS, CORD_Y, CORD_Z = 0.0035, 0.004, 0.032, (1.47, 1.33)
HOOD = ((-0.07, 0.0, 1.515), (0.05, 0.12, 0.065))  # a hood lying down behind the neck
POCKET_Z, POCKET_SIZE = 1.08, (0.02, 0.1, 0.055)  # a hoodie's front pocket
# face features on the head ellipsoid: ((y, z, depth out of its surface), half sizes); mirrored ones at +y
NOSE = ((0.0, 1.655, -0.004), (0.016, 0.011, 0.026))
LIPS = ((0.0, 1.618, -0.002), (0.004, 0.019, 0.0045))
EYE = ((0.032, 1.684, -0.003), (0.004, 0.013, 0.0075))
IRIS_RADIUS, IRIS_FORWARD = 0.0055, 0.0028
BROW = ((0.033, 1.703, -0.001), (0.004, 0.019, 0.0045))
EAR = ((0.004, 0.076, 1.668), (0.012, 0.008, 0.028))  # centre in the body frame, half sizes
LONG_HAIR = ((-0.06, 0.0, 1.58), (0.05, 0.085, 0.14))
BUN = ((-0.07, 0.0, 1.76), (0.04, 0.04, 0.04))
# hand below the wrist: palm (offset, half sizes); thumb from, to (offsets, y towards the body) and radius
PALM = ((0.006, 0.0, -0.072), (0.04, 0.018, 0.068))
THUMB = ((0.026, -0.012, -0.03), (0.05, -0.014, -0.068), 0.011)
# cloth folds: (amplitude as a share of the radius, whole waves around, waves along, where they gather)
TORSO_DRAPE = ((3, 8), (0.5, 2.0), lambda n: 0.25 + 0.75 * np.linspace(0, 1, n))  # amplitude from TOPS
SLEEVE_FOLDS = (0.05, (1, 3), (3.0, 7.0), lambda n: 0.15 + _bump(n, 0.55, 0.14) + 0.6 * _bump(n, 1.0, 0.1))
SHORT_SLEEVE_FOLDS = (0.02, (1, 3), (1.0, 2.0), lambda n: np.linspace(0.3, 1.0, n))
TROUSER_FOLDS = (0.03, (1, 3), (3.0, 6.0), lambda n: 0.2 + _bump(n, 0.5, 0.12) + _bump(n, 1.0, 0.1))  # knees, hems
SKIRT_FOLDS = (0.04, (5, 9), (0.2, 0.8), lambda n: np.linspace(0, 1, n))  # pleats opening towards the hem
LIP_SHADE = 0.78  # lips are the skin tone, darker
SCLERA_RGB, IRIS_RGB, ZIP_RGB = (232, 228, 222), (36, 26, 20), (150, 150, 152)
SKIN_TILE_M, HAIR_TILE_M = 0.1, 0.08
# (around, along) mesh resolution of each part: enough for smooth shading at 0.3 m, no more
DETAIL = {
    "torso": (32, 26), "sleeve": (16, 20), "short_sleeve": (16, 6), "arm": (10, 12), "pelvis": (28, 6),
    "skirt": (28, 10), "leg": (14, 16), "collar": (20, 2), "head": (18, 10), "hair": (16, 8), "hand": (8, 5),
    "feature": (6, 4), "rod": (6, 2), "shoe": (10, 5),
}
# (specular, shininess) of the materials: cloth is matte, skin a little glossy, shoes polished
MATTE, SKIN_SHINE, HAIR_SHINE, POLISH = (0.04, 0.05), (0.12, 0.25), (0.22, 0.35), (0.35, 0.5)


def _mirror(points, side: int) -> tuple:
    return tuple((x, side * y, z) for x, y, z in points)


class Person:
    """A person on a mocap body (kinematic, no collisions), all geoms in OCCLUDER_GROUP.

    Body frame: origin on the floor between the feet, +X the walking direction, +Z up.
    style "plain": the original flat-coloured capsules and boxes, built from four draws of `rng`.
    style "textured": a clothed body; it makes the same four draws, then one integer that seeds its
    own generator, so its look depends only on the scenario seed and `index`.
    """

    HALF_DEPTH = 0.12  # half extent front to back: what the camera sees while it walks past in profile
    HALF_WIDTH = 0.28  # half extent shoulder to shoulder, arms included: what it sees when facing the camera

    def __init__(self, root: mjcf.RootElement, index: int, rng: np.random.Generator, style: str = "textured"):
        if style not in PERSON_STYLES:
            raise choice_error("person style", style, PERSON_STYLES)
        shirt = np.r_[rng.uniform(0.1, 0.9, 3), 1.0]
        trousers = np.r_[rng.uniform(0.05, 0.4, 3), 1.0]
        skin = np.r_[np.array([0.85, 0.65, 0.5]) * rng.uniform(0.55, 1.0), 1.0]
        hair = np.r_[rng.uniform(0.05, 0.3) * np.ones(3), 1.0]
        self.style = style
        self.body = root.worldbody.add("body", name=f"person{index}", mocap=True)
        self.outfit: Outfit | None = None
        if style == "plain":
            _build_plain(self.body, shirt, trousers, skin, hair, self.HALF_DEPTH)
            return
        own = np.random.default_rng([int(rng.integers(2 ** 63)), 17, index])
        self.outfit = Outfit.sample(own)
        _Tailor(root, self.body, f"person{index}", own).dress(self.outfit)


def _build_plain(body, shirt, trousers, skin, hair, half_depth: float) -> None:
    """The original figure: flat-coloured capsules, spheres and a box torso."""
    common = {"contype": 0, "conaffinity": 0, "group": OCCLUDER_GROUP}
    for side in (1, -1):
        body.add("geom", type="capsule", fromto=[0, side * 0.09, 0.07, 0, side * 0.09, 0.9], size=[0.065],
                 rgba=trousers, **common)
        body.add("geom", type="box", pos=[0.04, side * 0.09, 0.03], size=[0.12, 0.05, 0.03], rgba=[0.1, 0.1, 0.1, 1],
                 **common)
        body.add("geom", type="capsule", fromto=[0, side * 0.235, 1.47, 0.03, side * 0.235, 0.95], size=[0.045],
                 rgba=shirt, **common)
        body.add("geom", type="sphere", pos=[0.035, side * 0.235, 0.88], size=[0.05], rgba=skin, **common)
    body.add("geom", type="box", pos=[0, 0, 1.22], size=[half_depth, 0.19, 0.30], rgba=shirt, **common)
    body.add("geom", type="capsule", fromto=[0, 0, 1.5, 0, 0, 1.6], size=[0.05], rgba=skin, **common)
    body.add("geom", type="sphere", pos=[0.01, 0, 1.7], size=[0.105], rgba=skin, **common)
    body.add("geom", type="ellipsoid", pos=[-0.015, 0, 1.75], size=[0.1, 0.1, 0.07], rgba=hair, **common)


class _Tailor:
    """Builds one textured person: parts are meshed per material, then added as one geom each."""

    def __init__(self, root: mjcf.RootElement, body, prefix: str, rng: np.random.Generator):
        self.root, self.body, self.prefix, self.rng = root, body, prefix, rng
        self.materials: dict[str, tuple] = {}  # key: (material element, texture tile in metres)
        self.parts: dict[str, list[MeshData]] = {}

    # ------------------------------------------------------------------ assets

    def material(self, key: str, image: np.ndarray | None = None, rgb: RGB | None = None,
                 finish: tuple[float, float] = MATTE, tile_m: float = 1.0) -> None:
        """A material, textured from an in-memory RGB image (PNG bytes, no file) or of one colour."""
        kw: dict = {"specular": finish[0], "shininess": finish[1]}
        if image is not None:
            ok, png = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
            if not ok:
                raise ConfigError(f"could not encode the {key} texture of {self.prefix}")
            kw["texture"] = self.root.asset.add("texture", name=f"{self.prefix}_{key}", type="2d",
                                                file=mjcf.Asset(png.tobytes(), ".png"))
        if rgb is not None:
            kw["rgba"] = [*(np.asarray(rgb, float) / 255.0), 1.0]
        self.materials[key] = (self.root.asset.add("material", name=f"{self.prefix}_{key}", **kw), tile_m)
        self.parts[key] = []

    def tube(self, key: str, detail: str, tube: Tube, folds: tuple | None = None,
             cap_rings: int = CAP_RINGS) -> MeshData:
        """Mesh a tube into the material's part list; folds = (amplitude, around, along, envelope(n))."""
        n_around, n_along = DETAIL[detail]
        gains = fold_gains(self.rng, n_along, n_around, *folds[:3], envelope=folds[3](n_along)) if folds else None
        mesh = tube_mesh(tube, self.materials[key][1], n_around, n_along, gains, cap_rings)
        self.parts[key].append(mesh)
        return mesh

    def blob(self, key: str, detail: str, centre, size) -> None:
        self.parts[key].append(ellipsoid_mesh(centre, size, self.materials[key][1], *DETAIL[detail]))

    def rod(self, key: str, points, radius: float) -> None:
        """A thin round-ended tube (neck, thumb, drawstring, zip) through the points."""
        r = (radius,) * len(points)
        self.tube(key, "rod", Tube(tuple(map(tuple, points)), r, r, start="round", end="round"), cap_rings=2)

    def sew(self) -> None:
        """One mesh asset and one geom per material."""
        for key, meshes in self.parts.items():
            if not meshes:
                continue
            mesh = merge_meshes(meshes)
            name = f"{self.prefix}_{key}"
            asset = self.root.asset.add("mesh", name=name, file=mjcf.Asset(_msh_bytes(mesh), ".msh"))
            self.body.add("geom", name=name, type="mesh", mesh=asset, material=self.materials[key][0],
                          contype=0, conaffinity=0, group=OCCLUDER_GROUP)

    # ------------------------------------------------------------------ the person

    def dress(self, o: Outfit) -> None:
        self.material("top", o.top_fabric.texture(), tile_m=o.top_fabric.tile_m)
        self.material("bottom", o.bottom_fabric.texture(), tile_m=o.bottom_fabric.tile_m)
        self.material("skin", skin_texture(o.skin, self._seed()), finish=SKIN_SHINE, tile_m=SKIN_TILE_M)
        self.material("hair", hair_texture(o.hair, self._seed()), finish=HAIR_SHINE, tile_m=HAIR_TILE_M)
        torso = self.torso(o)
        self.arms(o)
        self.lower(o)
        self.head(o)
        self.shoes(o)
        self.trim(o, torso)
        self.sew()

    def _seed(self) -> int:
        return int(self.rng.integers(2 ** 31))

    def torso(self, o: Outfit) -> MeshData:
        _, _, hem, ease, amplitude = TOPS[o.top]
        last = TORSO_PROFILE[-1]
        hem_row = (hem, last[1], last[2] + HEM_FLARE, last[3] + HEM_FLARE)
        rows = [r for r in TORSO_PROFILE if r[0] > hem + 0.02] + [hem_row]
        z, x, a, b = np.array(rows).T
        tube = Tube(tuple(zip(x, 0 * x, z)), tuple(a + ease), tuple(b * o.girth + ease),
                    TORSO_SQUARENESS, start="flat", end="flat")
        return self.tube("top", "torso", tube, (amplitude, *TORSO_DRAPE))

    def arms(self, o: Outfit) -> None:
        sleeve_kind, ease = TOPS[o.top][1], TOPS[o.top][3]
        for side in (1, -1):
            k = np.array(_mirror(ARM_KNOTS, side))
            if sleeve_kind == "short":
                arm = Tube(tuple(map(tuple, k)), ARM_RADII, tuple(ARM_FLATTEN * np.array(ARM_RADII)), end="round")
                self.tube("skin", "arm", arm)
                cut = k[1] + SHORT_SLEEVE * (k[2] - k[1])
                r = np.array(SHORT_SLEEVE_RADII) + ease
                sleeve = Tube((tuple(k[0]), tuple(k[1]), tuple(cut)), tuple(r), tuple(ARM_FLATTEN * r))
                self.tube("top", "short_sleeve", sleeve, SHORT_SLEEVE_FOLDS)
            else:
                r = np.array(SLEEVE_RADII) + ease
                sleeve = Tube(tuple(map(tuple, k)), tuple(r), tuple(ARM_FLATTEN * r))
                self.tube("top", "sleeve", sleeve, SLEEVE_FOLDS)
            self.hand(k[-1], side)

    def hand(self, wrist: np.ndarray, side: int) -> None:
        """A palm and a thumb that points forward, hanging below the wrist."""
        self.blob("skin", "hand", wrist + PALM[0], PALM[1])
        frm, to, radius = THUMB
        mirror = np.array([1.0, side, 1.0])
        self.rod("skin", (wrist + np.multiply(frm, mirror), wrist + np.multiply(to, mirror)), radius)

    def lower(self, o: Outfit) -> None:
        g = o.girth
        if o.bottom == "skirt":
            z, x, a, b = np.array(SKIRT + ((o.skirt_hem, -0.004, *SKIRT_HEM_SIZE),)).T
            skirt = Tube(tuple(zip(x, 0 * x, z)), tuple(a), tuple(b * g), TORSO_SQUARENESS, "flat", "flat")
            self.tube("bottom", "skirt", skirt, SKIRT_FOLDS)
            radii, leg_key, end, folds = BARE_LEG_RADII, "skin", "round", None
        else:
            z, x, a, b = np.array(PELVIS).T
            self.tube("bottom", "pelvis", Tube(tuple(zip(x, 0 * x, z)), tuple(a), tuple(b * g), TORSO_SQUARENESS,
                                               "flat", "round"))
            radii, leg_key, end = (JEANS_RADII if o.bottom == "jeans" else TROUSER_RADII), "bottom", "flat"
            folds = TROUSER_FOLDS
        r = tuple(np.array(radii) * g)
        for side in (1, -1):
            self.tube(leg_key, "leg", Tube(_mirror(LEG_KNOTS, side), r, r, start="round", end=end), folds)

    def head(self, o: Outfit) -> None:
        self.material("lips", rgb=tuple(int(LIP_SHADE * c) for c in o.skin), finish=SKIN_SHINE)
        self.material("sclera", rgb=SCLERA_RGB, finish=POLISH)
        self.material("iris", rgb=IRIS_RGB, finish=POLISH)
        frm, to, r = NECK
        self.rod("skin", (frm, to), r)
        self.blob("skin", "head", HEAD_CENTRE, HEAD_SIZE)
        self.blob("skin", "feature", _on_head(*NOSE[0]), NOSE[1])
        self.blob("lips", "feature", _on_head(*LIPS[0]), LIPS[1])
        for side in (1, -1):
            (x, y, z), size = EAR
            self.blob("skin", "feature", (x, side * y, z), size)
            (y, z, depth), size = EYE
            eye = _on_head(side * y, z, depth)
            self.blob("sclera", "feature", eye, size)
            self.blob("iris", "feature", eye + [IRIS_FORWARD, 0, 0], (IRIS_RADIUS,) * 3)
            (y, z, depth), size = BROW
            self.blob("hair", "feature", _on_head(side * y, z, depth), size)
        self.hair(o.hair_style)

    def hair(self, style: str) -> None:
        """A crown cap (its front edge is the hairline) and a back piece down to the nape, plus extras."""
        thin = HAIR_BUZZ_SCALE if style == "buzz" else 1.0
        for pos, size in HAIR_PIECES:
            self.blob("hair", "hair", pos, np.array(size) * thin)
        if style == "long":
            self.blob("hair", "hair", *LONG_HAIR)
        elif style == "bun":
            self.blob("hair", "hair", *BUN)

    def shoes(self, o: Outfit) -> None:
        if o.shoes == "sneaker":
            canvas = Fabric("plain_weave", (o.shoe_colour,), self._seed())
            self.material("shoe", canvas.texture(), finish=MATTE, tile_m=canvas.tile_m)
        else:
            self.material("shoe", rgb=o.shoe_colour, finish=POLISH)
        self.material("sole", rgb=o.sole_colour, finish=MATTE)
        up = (0.0, 0.0, 1.0)  # shoes run along +X, so their cross-sections are measured from +Z
        (x0, x1), half_t, half_w = SOLE
        for side in (1, -1):
            y = side * LEG_KNOTS[-1][1]
            knots = tuple((x, y, z) for (x, z), _ in SHOE_UPPER)
            a, b = zip(*(size for _, size in SHOE_UPPER))
            self.tube("shoe", "shoe", Tube(knots, a, b, start="round", end="round", forward=up))
            sole = Tube(((x0, y, half_t), (x1, y, half_t)), (half_t,) * 2, (half_w,) * 2, 4.0, "round", "round", up)
            self.tube("sole", "shoe", sole, cap_rings=2)

    def trim(self, o: Outfit, torso: MeshData) -> None:
        """Collars, buttons, zips, hoods and pockets: what makes a garment read as that garment."""
        (x0, z0, a0, b0), (x1, z1, a1, b1) = COLLARS.get(o.top, CREW_NECK)
        self.tube("top", "collar", Tube(((x0, 0, z0), (x1, 0, z1)), (a0, a1), (b0, b1), start="flat", end="flat"))
        hem = TOPS[o.top][2]
        if o.top == "shirt":
            self.material("trim", rgb=_colour(self.rng, ("white", "cream", "black", "brown")), finish=POLISH)
            for z in np.arange(1.46, hem + 0.04, -BUTTON_PITCH):
                self.blob("trim", "feature", (_front_x(torso, z) + 0.001, 0, z), BUTTON_SIZE)
        elif o.top == "jacket":
            self.material("trim", rgb=ZIP_RGB, finish=POLISH)
            self.rod("trim", [(_front_x(torso, z) + 0.001, 0, z) for z in np.linspace(1.5, hem + 0.01, 8)], ZIP_RADIUS)
        elif o.top == "hoodie":
            self.blob("top", "hair", *HOOD)
            self.blob("top", "hair", (_front_x(torso, POCKET_Z) - POCKET_SIZE[0] + 0.008, 0, POCKET_Z), POCKET_SIZE)
            self.material("trim", rgb=_colour(self.rng, ("white", "cream", "black")), finish=MATTE)  # drawstrings
            for side in (1, -1):
                cord = [(_front_x(torso, z) + CORD_RADIUS - 0.001, side * CORD_Y, z) for z in np.linspace(*CORD_Z, 4)]
                self.rod("trim", cord, CORD_RADIUS)


def _msh_bytes(mesh: MeshData) -> bytes:
    """MuJoCo's binary MSH mesh format (counts, then float32 vertices, normals, texcoords, int32 faces):
    far quicker to hand over than MJCF text attributes."""
    counts = np.array([len(mesh.vertices), len(mesh.normals), len(mesh.texcoords), len(mesh.faces)], np.int32)
    arrays = (mesh.vertices, mesh.normals, mesh.texcoords)
    floats = [a.astype(np.float32).tobytes() for a in arrays]
    return b"".join([counts.tobytes(), *floats, mesh.faces.astype(np.int32).tobytes()])


def _on_head(y: float, z: float, depth: float) -> np.ndarray:
    """Point on the front of the head ellipsoid at (y, z), moved `depth` along +X (negative: sunk in)."""
    c, s = HEAD_CENTRE, HEAD_SIZE
    inside = 1.0 - ((y - c[1]) / s[1]) ** 2 - ((z - c[2]) / s[2]) ** 2
    return np.array([c[0] + s[0] * np.sqrt(max(inside, 0.0)) + depth, y, z])


def _front_x(mesh: MeshData, z: float) -> float:
    """x of a tube's front centre line at height z (where buttons and zips go)."""
    v = mesh.vertices
    front = v[(np.abs(v[:, 1]) < 0.012) & (v[:, 0] > 0)]
    order = np.argsort(front[:, 2])
    return float(np.interp(z, front[order, 2], front[order, 0]))
