"""The natural benchmark's vocabulary: its picture sources, occluder kinds, frame rate and seed streams, and the
seeded generator every draw comes from."""

from __future__ import annotations

import zlib

import numpy as np

# ---------------------------------------------------------------------------------------------------------------------
# Sources and kinds
# ---------------------------------------------------------------------------------------------------------------------

NATURAL_PHOTOS = ("photo_china", "photo_flower", "photo_aero", "photo_ascent")  # every allowed real photo
# procedural pictures: printed matter and materials, with the self-similar ones (fur, foliage, brick,
# gravel, bark, mosaic) that defeat a global re-detection
NATURAL_PROCEDURAL = ("fur", "foliage", "brick", "gravel", "bark", "poster", "wood", "marble", "mosaic", "corkboard")
NATURAL_SOURCES: tuple[str, ...] = NATURAL_PHOTOS + NATURAL_PROCEDURAL
NATURAL_KINDS = ("clear", "walk_by", "pause", "partial")  # the default set: its figures stay comparable
# harder occluders, asked for by name: a person dressed in the picture's own texture, a hand close to the lens
# (skin, defocused) and a long pause (several seconds hidden while the phone keeps moving)
EXTRA_KINDS = ("lookalike", "hand", "long")
ALL_KINDS = NATURAL_KINDS + EXTRA_KINDS
OCCLUDED_KINDS = ("walk_by", "pause", "partial", *EXTRA_KINDS)
DEFAULT_SEEDS = (500, 501)

FPS = 30.0  # as the simulator's scenarios
T_REF_S = 5.0  # a 150-frame sequence; the person's schedule is compressed for shorter ones
MIN_SIZE = (320, 240)  # the largest ROI (160 px wide) must fit well inside the view
DISTORTION_FOVY_DEG = 45.0  # K for lens distortion: the simulator's default CameraConfig.fovy

# seed streams (rng = default_rng([crc32(source), seed, STREAM, ...]))
PICTURE_STREAM, PATH_STREAM, ROI_STREAM, PERSON_STREAM = 1, 2, 3, 4


def _rng(source: str, seed: int, *stream: int) -> np.random.Generator:
    return np.random.default_rng([zlib.crc32(source.encode()), seed, *stream])


def _u(rng: np.random.Generator, lo_hi) -> float:
    return float(rng.uniform(*lo_hi))
