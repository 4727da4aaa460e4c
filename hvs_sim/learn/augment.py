"""Frame degradations for residual-regressor training: partial occlusion, blur, lighting, and what a
real camera adds (shot and read noise in linear light, JPEG at a random quality)."""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.sensor import decode, encode, jpeg

SENSOR_SHARE = 0.7  # of training samples that go through the sensor model (the rest stay as rendered)


def occlude(frame: np.ndarray, corners: np.ndarray, rng: np.random.Generator, max_cover: float = 0.45) -> float:
    """Cover a band of the target from one side with a random colour or texture; returns its share."""
    x0, y0 = corners.min(0)
    x1, y1 = corners.max(0)
    cover = rng.uniform(0.05, max_cover)
    side = rng.integers(4)
    if side == 0:
        box = (x0 - 20, y0 - 20, x0 + cover * (x1 - x0), y1 + 20)
    elif side == 1:
        box = (x1 - cover * (x1 - x0), y0 - 20, x1 + 20, y1 + 20)
    elif side == 2:
        box = (x0 - 20, y0 - 20, x1 + 20, y0 + cover * (y1 - y0))
    else:
        box = (x0 - 20, y1 - cover * (y1 - y0), x1 + 20, y1 + 20)
    xa, ya, xb, yb = (round(v) for v in box)
    xa, ya = max(xa, 0), max(ya, 0)
    xb, yb = min(xb, frame.shape[1]), min(yb, frame.shape[0])
    if xb <= xa or yb <= ya:
        return 0.0
    if rng.random() < 0.5:
        frame[ya:yb, xa:xb] = rng.integers(0, 256, 3)
    else:
        tex = rng.integers(0, 256, (max(1, (yb - ya) // 8), max(1, (xb - xa) // 8), 3)).astype(np.uint8)
        frame[ya:yb, xa:xb] = cv2.resize(tex, (xb - xa, yb - ya), interpolation=cv2.INTER_LINEAR)
    return float(cover)


def blur(frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    if rng.random() < 0.5:
        return cv2.GaussianBlur(frame, (0, 0), rng.uniform(0.6, 2.0))
    n = int(rng.integers(3, 10))
    k = np.zeros((n, n), np.float32)
    k[n // 2] = 1.0
    M = cv2.getRotationMatrix2D(((n - 1) / 2, (n - 1) / 2), rng.uniform(0, 180), 1.0)
    k = cv2.warpAffine(k, M, (n, n))
    return cv2.filter2D(frame, -1, k / max(k.sum(), 1e-6))


def lighting(frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    gain = rng.uniform(0.75, 1.25)
    bias = rng.uniform(-20, 20)
    gamma = rng.uniform(0.8, 1.25)
    f = 255.0 * (np.clip(frame.astype(np.float32) * gain + bias, 0, 255) / 255.0) ** gamma
    f += rng.normal(0, rng.uniform(0, 4), f.shape)
    return np.clip(f, 0, 255).astype(np.uint8)


SENSOR_WHITE_E = (150.0, 2000.0)  # electrons at white: low light … a good phone in daylight
SENSOR_READ_E = (2.0, 8.0)
JPEG_QUALITY = (40, 95)


def sensor(frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Shot + read noise in linear light (as sensor.py), then JPEG at a random quality."""
    lin = decode(frame)
    white, read = rng.uniform(*SENSOR_WHITE_E), rng.uniform(*SENSOR_READ_E)
    electrons = lin * np.float32(white)
    noisy = electrons + np.sqrt(electrons + np.float32(read ** 2)) * rng.standard_normal(lin.shape, dtype=np.float32)
    return jpeg(encode(np.clip(noisy / np.float32(white), 0.0, 1.0)), int(rng.integers(*JPEG_QUALITY)))


def degrade(frame: np.ndarray, corners: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """A degraded copy and what was done to it."""
    out = frame.copy()
    info = {"occluded": 0.0, "blurred": False}
    if rng.random() < 0.5:
        info["occluded"] = occlude(out, corners, rng)
    if rng.random() < 0.4:
        out = blur(out, rng)
        info["blurred"] = True
    out = lighting(out, rng)
    if rng.random() < SENSOR_SHARE:
        out = sensor(out, rng)
    return out, info
