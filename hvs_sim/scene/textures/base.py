"""The texture families' shared building blocks: the canvas a generator draws on, pixel grids, remapping,
blending, shading, Voronoi cells, palettes and sensor grain.

The noise octaves the families are built from (value noise, fBm, turbulence) are in `hvs_sim/scene/noise.py`,
beside the tiling noise and the weaves that the people's fabrics use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

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
