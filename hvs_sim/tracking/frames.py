"""Validation of frames and ROIs handed to a tracker, and the grey working image."""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.errors import InputError

MIN_ROI = 24  # pixels: pool2 has stride 4 and the LK needs a few feature cells plus a border


def check_frame(frame, expected_shape: tuple[int, int] | None = None) -> np.ndarray:
    """Return the frame as H×W×3 uint8 RGB, or raise InputError saying what is accepted."""
    if not isinstance(frame, np.ndarray):
        raise InputError(f"frame must be a numpy array (H×W×3 uint8 RGB), got {type(frame).__name__}")
    if frame.ndim != 3 or frame.shape[2] != 3:
        raise InputError(f"frame must have shape H×W×3 (RGB), got shape {frame.shape}")
    if frame.shape[0] < MIN_ROI or frame.shape[1] < MIN_ROI:
        raise InputError(f"frame must be at least {MIN_ROI}×{MIN_ROI} pixels, got {frame.shape[1]}×{frame.shape[0]}")
    if frame.dtype == np.uint8:
        out = frame
    elif frame.dtype in (np.float32, np.float64):
        if not np.isfinite(frame).all():
            raise InputError("frame contains NaN or inf; accepted: uint8 RGB, or float RGB with finite values in [0, 255]")
        if frame.min() < 0 or frame.max() > 255:
            raise InputError(f"float frame values must lie in [0, 255], got [{frame.min():.3g}, {frame.max():.3g}]")
        if frame.max() <= 1.0 and np.any(frame != np.round(frame)):
            # read as [0, 255] it would be a black frame; which scale was meant cannot be told, so say so
            raise InputError("float frame values lie in [0, 1]; hvs_sim reads float frames on the 0–255 scale: "
                             "pass (frame * 255) or a uint8 image")
        out = np.round(frame).astype(np.uint8)
    else:
        raise InputError(f"frame dtype must be uint8 (or float32/float64 in [0, 255]), got {frame.dtype}")
    if expected_shape is not None and out.shape[:2] != tuple(expected_shape):
        raise InputError(f"frame size {out.shape[1]}×{out.shape[0]} differs from the size at init "
                         f"{expected_shape[1]}×{expected_shape[0]}; re-init the tracker for a new size")
    return out


def check_roi(roi, frame_shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """Validate (x, y, w, h) ints inside the frame and at least MIN_ROI on each side."""
    try:
        vals = [v for v in roi]
    except TypeError:
        raise InputError(f"roi must be (x, y, w, h) integers, got {roi!r}") from None
    if len(vals) != 4 or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in vals):
        raise InputError(f"roi must be 4 integers (x, y, w, h), got {roi!r}")
    x, y, w, h = (int(v) for v in vals)
    H, W = frame_shape
    if w < MIN_ROI or h < MIN_ROI:
        raise InputError(f"roi must be at least {MIN_ROI}×{MIN_ROI} pixels (feature stride 4 plus border), got {w}×{h}")
    if x < 0 or y < 0 or x + w > W or y + h > H:
        raise InputError(f"roi {(x, y, w, h)} lies outside the {W}×{H} frame; it must satisfy 0 <= x, x + w <= {W}, "
                         f"0 <= y, y + h <= {H}")
    return x, y, w, h


def to_grey(frame: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY)


def roi_center(roi) -> np.ndarray:
    x, y, w, h = roi
    return np.array([x + (w - 1) / 2.0, y + (h - 1) / 2.0])


def roi_corners(roi) -> np.ndarray:
    """Outer pixel edges of the ROI (TL, TR, BR, BL) in the pixel-centre convention."""
    x, y, w, h = roi
    return np.array([[x - 0.5, y - 0.5], [x + w - 0.5, y - 0.5], [x + w - 0.5, y + h - 0.5], [x - 0.5, y + h - 0.5]])


def roi_from_corners(corners: np.ndarray) -> tuple[int, int, int, int]:
    """Integer ROI inside the target's projected outline: the axis-aligned box of its inner edges, or,
    when the target is turned far about the optical axis (that box thins to a sliver), the largest
    box centred on it that fits inside the outline."""
    x0 = int(np.ceil(np.sort(corners[:, 0])[1]))
    x1 = int(np.floor(np.sort(corners[:, 0])[2]))
    y0 = int(np.ceil(np.sort(corners[:, 1])[1]))
    y1 = int(np.floor(np.sort(corners[:, 1])[2]))
    inner = (x0, y0, x1 - x0 + 1, y1 - y0 + 1)
    centred = _inscribed_box(np.asarray(corners, float))
    if centred is not None and centred[2] * centred[3] > INSCRIBED_GAIN * max(inner[2], 0) * max(inner[3], 0):
        return centred
    return inner


def inset_roi(roi, px: int) -> tuple[int, int, int, int]:
    """The ROI `px` pixels inside its edges on every side (negative: grown that much beyond them); InputError when
    that leaves less than MIN_ROI."""
    x, y, w, h = roi
    if px == 0:  # nothing to take away: a box too small for a tracker is for the tracker's init to refuse
        return x, y, w, h
    if w - 2 * px < MIN_ROI or h - 2 * px < MIN_ROI:
        raise InputError(f"an ROI of {w}×{h} px inset by {px} px on each side is under the {MIN_ROI}×{MIN_ROI} px "
                         "minimum: the target is too small in the image for that inset")
    return x + px, y + px, w - 2 * px, h - 2 * px


INSCRIBED_GAIN = 1.2  # the centred box replaces the inner-edge box only when clearly larger (large rolls)


def _inside_convex(quad: np.ndarray, pts: np.ndarray) -> np.ndarray:
    edges = np.roll(quad, -1, axis=0) - quad
    rel = pts[:, None, :] - quad[None]
    cross = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]
    return np.all(cross >= 0, axis=1) | np.all(cross <= 0, axis=1)


def _inscribed_box(quad: np.ndarray) -> tuple[int, int, int, int] | None:
    """Largest integer box centred on the quad's centroid inside it, over a range of aspect ratios."""
    c = quad.mean(0)
    best = None
    for aspect in np.geomspace(0.25, 4.0, 25):  # width / height
        lo, hi = 0.0, float(np.ptp(quad, axis=0).max())
        for _ in range(30):
            h = 0.5 * (lo + hi)
            half = np.array([0.5 * h * aspect, 0.5 * h])
            box = c + half * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
            lo, hi = (h, hi) if _inside_convex(quad, box).all() else (lo, h)
        w_px, h_px = int(np.floor(lo * aspect)), int(np.floor(lo))
        if best is None or w_px * h_px > best[2] * best[3]:
            best = (int(np.ceil(c[0] - 0.5 * lo * aspect)), int(np.ceil(c[1] - 0.5 * lo)), w_px, h_px)
    return best if best and best[2] > 0 and best[3] > 0 else None
