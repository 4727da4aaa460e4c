"""Low-poly meshes for the people: tubes through knots (torso, sleeves, legs, rods), ellipsoids, cloth folds,
with outward normals and texture coordinates in tiles of cloth; merged per material by the tailor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hvs_sim.errors import choice_error

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
