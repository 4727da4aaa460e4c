"""Shared test set-up: headless GL, and the synthetic flag frame several modules track on."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

from functools import lru_cache

import cv2
import numpy as np
import pytest

FRAME_H, FRAME_W = 480, 640
FLAG_NAMES_ON_BOARD = ("star_field", "crescent", "saltire", "rings")


@lru_cache(maxsize=1)
def _flag_frame() -> np.ndarray:
    from hvs_sim.scene.flag_art import draw_flag

    rng = np.random.default_rng(0)
    frame = np.clip(rng.normal(180, 12, (FRAME_H, FRAME_W, 3)), 0, 255).astype(np.uint8)
    frame = cv2.GaussianBlur(frame, (0, 0), 1.0)
    for k, name in enumerate(FLAG_NAMES_ON_BOARD):
        img = cv2.resize(draw_flag(name), (150, 100), interpolation=cv2.INTER_AREA)
        y, x = 160 + 130 * (k // 2) - 60, 140 + 210 * (k % 2)
        frame[y:y + 100, x:x + 150] = img
    return frame


@pytest.fixture
def flag_frame() -> np.ndarray:
    """640×480 RGB: four flags on a textured board, like the simulator's wall (a fresh copy per test).
    The first flag covers x 140–289, y 100–199."""
    return _flag_frame().copy()
