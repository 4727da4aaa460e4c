"""The tracker contract every method shares: `init(frame, roi)`, `update(frame) -> Track`.

The base class owns input validation and the guarantee that a Track is always finite: when a
method cannot produce a trustworthy estimate it reports mode "lost" and keeps the last pose.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from hvs_sim.errors import ConfigError, InputError, StateError
from hvs_sim.tracking.frames import check_frame, check_roi, roi_center, roi_corners
from hvs_sim.tracking.warp import apply, fit_similarity, local_affine, matrix_to_pose


class Mode(StrEnum):
    """How a Track was obtained. A StrEnum: `track.mode == "align"` and CSV/JSON output keep working."""

    ALIGN = "align"  # the target was seen and aligned in this frame
    PREDICT = "predict"  # not aligned: moved by the scene's motion or extrapolated by the predictor
    LOST = "lost"  # no trustworthy estimate: the pose is held where it was


MODES = tuple(m.value for m in Mode)


@dataclass(frozen=True)
class Track:
    center: np.ndarray  # (2,) frame pixels, pixel centres at integers
    corners: np.ndarray  # (4, 2) template corners (outer pixel edges of the ROI) under the warp
    pose: np.ndarray  # (tx, ty, theta, scale) relative to the template at init
    mode: Mode  # align | predict | lost
    occlusion: float  # OP_t in [0, 1]
    score: float  # global match score
    ms: float = 0.0  # wall time of this update
    # how much to trust this pose, in [0, 1]: 0 when lost; for the deep trackers the template's
    # trackability (1 for a textured template, lower for one init was told to accept anyway) times
    # the visible share (1 − OP_t) when aligned; the hybrid's unaligned poses halve it every second
    # since the last alignment, and halve it again when the predictor alone gives them
    confidence: float = 1.0


@dataclass
class Estimate:
    """What a method returns per frame: frame-from-template matrix (full resolution) and status."""

    A: np.ndarray
    mode: Mode
    occlusion: float
    score: float
    confidence: float | None = None  # None: the base class derives it from mode and OP_t


def _finite(*xs) -> bool:
    return all(np.all(np.isfinite(np.asarray(x, float))) for x in xs)


class Tracker:
    """Base class: subclasses implement `_init(frame, roi)` and `_update(frame) -> Estimate`."""

    name = "base"
    warp = "similarity"  # the warp model it estimates (warp.WARPS): a homography gives perspective corners
    # what a servo loop asks of it (servo/plan.py): seed(A) places its estimate (a goal template seeded on the first
    # frame), and it takes the loop's grown near-goal template (servo/templates.py)
    can_seed = True
    near_goal = True

    def __init__(self):
        self._shape: tuple[int, int] | None = None
        self.A = np.eye(3)
        self.template_confidence = 1.0  # trackability of the template taken at init, in [0, 1] (set by _init)
        self.notes: list[str] = []  # what a user should be told about this run (a weak template, a choice made)

    @property
    def working_scale(self) -> float | None:
        """The resolution it aligns at, relative to the frame's (None: it has no such setting)."""
        return None

    def with_scale(self, scale: float) -> Tracker:
        """A fresh tracker with this one's settings that aligns at `scale` of the frame (a servo's near-goal template:
        a large box tracked at a lower resolution). ConfigError where it has no working scale."""
        raise ConfigError(f"tracker {self.name!r} has no working scale to change")

    def init(self, frame, roi) -> Track:
        """Take the template at `roi` of `frame`. Atomic: if it raises, the tracker is uninitialised
        (update() then says so) rather than half-way between two templates."""
        frame = check_frame(frame)
        roi = check_roi(roi, frame.shape[:2])
        self._shape = None
        self.roi = roi
        self.center0 = roi_center(roi)
        self.corners0 = roi_corners(roi)
        self.A = np.eye(3)
        self.template_confidence = 1.0
        self.notes = []
        self._init(frame, roi)
        self._shape = frame.shape[:2]
        return self._track(Estimate(self.A, Mode.ALIGN, 0.0, 1.0, self.template_confidence), 0.0)

    def seed(self, A) -> Track:
        """Put the estimate at A (3×3 frame-from-template warp) for the next frame, which then aligns from it.

        For a template taken from another image than the frames that follow (teach-by-showing: the goal
        image, with the target's four corners marked in the first frame, `LoopConfig.template_from`).
        A similarity tracker takes the similarity nearest A (least squares over the template's corners)."""
        if self._shape is None:
            raise StateError(f"{self.name}: seed() called before init(frame, roi)")
        try:
            A = np.array(A, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"seed warp must be a 3×3 array of numbers, got {type(A).__name__}") from None
        if A.shape != (3, 3) or not _finite(A) or abs(A[2, 2]) < 1e-12:
            raise InputError(f"seed warp must be a finite 3×3 matrix with A[2, 2] != 0, got shape {A.shape}")
        A = A / A[2, 2]
        w = self.corners0 @ A[2, :2] + A[2, 2]
        if np.any(w <= 0):
            raise InputError("seed warp sends a template corner to infinity or behind the camera")
        if self.warp == "similarity":
            A = fit_similarity(self.corners0, apply(A, self.corners0))
        if not _finite(A) or not abs(np.linalg.det(local_affine(A, self.center0)[:2, :2])) > 1e-6:
            raise InputError("seed warp is singular at the template (it folds the template to a line or a point)")
        self.A = A
        self._seed(A)
        return self._track(Estimate(self.A, Mode.PREDICT, 0.0, 0.0, self.template_confidence), 0.0)

    def _seed(self, A: np.ndarray) -> None:
        """Hook: a method that keeps its own estimate beside `self.A` moves it to A (seed)."""

    def update(self, frame) -> Track:
        if self._shape is None:
            raise StateError(f"{self.name}: update() called before init(frame, roi)")
        frame = check_frame(frame, self._shape)
        t0 = time.perf_counter()
        est = self._update(frame)
        # invertible where the template is (the local affine part: a homography's own 2×2 block can be singular)
        ok = _finite(est.A) and est.mode in MODES and abs(np.linalg.det(local_affine(est.A, self.center0)[:2, :2])) > 1e-6
        if ok and est.mode != Mode.LOST:
            self.A = est.A
        mode = Mode(est.mode) if ok else Mode.LOST
        occ = float(np.clip(est.occlusion, 0.0, 1.0)) if _finite(est.occlusion) else 1.0
        score = float(est.score) if _finite(est.score) else 0.0
        conf = est.confidence if ok and est.confidence is not None and _finite(est.confidence) else None
        if mode == Mode.LOST:
            conf = 0.0
        elif conf is None:
            conf = self.template_confidence * (1.0 - occ)
        return self._track(Estimate(self.A, mode, occ, score, float(np.clip(conf, 0.0, 1.0))),
                           1e3 * (time.perf_counter() - t0))

    def _track(self, est: Estimate, ms: float) -> Track:
        return Track(center=apply(est.A, self.center0[None])[0], corners=apply(est.A, self.corners0),
                     pose=matrix_to_pose(est.A, self.center0), mode=Mode(est.mode), occlusion=est.occlusion,
                     score=est.score, ms=ms, confidence=float(est.confidence))

    def _init(self, frame: np.ndarray, roi) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _update(self, frame: np.ndarray) -> Estimate:  # pragma: no cover - abstract
        raise NotImplementedError
