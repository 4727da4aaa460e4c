"""The tracker contract every method shares: `init(frame, roi)`, `update(frame) -> Track`.

The base class owns input validation and the guarantee that a Track is always finite: when a
method cannot produce a trustworthy estimate it reports mode "lost" and keeps the last pose.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hvs_sim.errors import StateError
from hvs_sim.tracking.frames import check_frame, check_roi, roi_center, roi_corners
from hvs_sim.tracking.warp import apply, matrix_to_pose

MODES = ("align", "predict", "lost")


@dataclass(frozen=True)
class Track:
    center: np.ndarray  # (2,) frame pixels, pixel centres at integers
    corners: np.ndarray  # (4, 2) template corners (outer pixel edges of the ROI) under the warp
    pose: np.ndarray  # (tx, ty, theta, scale) relative to the template at init
    mode: str  # "align" | "predict" | "lost"
    occlusion: float  # OP_t in [0, 1]
    score: float  # global match score
    ms: float = 0.0  # wall time of this update


@dataclass
class Estimate:
    """What a method returns per frame: frame-from-template matrix (full resolution) and status."""

    A: np.ndarray
    mode: str
    occlusion: float
    score: float


def _finite(*xs) -> bool:
    return all(np.all(np.isfinite(np.asarray(x, float))) for x in xs)


class Tracker:
    """Base class: subclasses implement `_init(frame, roi)` and `_update(frame) -> Estimate`."""

    name = "base"

    def __init__(self):
        self._shape: tuple[int, int] | None = None
        self.A = np.eye(3)

    def init(self, frame, roi) -> Track:
        frame = check_frame(frame)
        roi = check_roi(roi, frame.shape[:2])
        self._shape = frame.shape[:2]
        self.roi = roi
        self.center0 = roi_center(roi)
        self.corners0 = roi_corners(roi)
        self.A = np.eye(3)
        self._init(frame, roi)
        return self._track(Estimate(self.A, "align", 0.0, 1.0), 0.0)

    def update(self, frame) -> Track:
        if self._shape is None:
            raise StateError(f"{self.name}: update() called before init(frame, roi)")
        frame = check_frame(frame, self._shape)
        t0 = time.perf_counter()
        est = self._update(frame)
        ok = _finite(est.A) and est.mode in MODES and abs(np.linalg.det(est.A[:2, :2])) > 1e-6
        if ok and est.mode != "lost":
            self.A = est.A
        mode = est.mode if ok else "lost"
        occ = float(np.clip(est.occlusion, 0.0, 1.0)) if _finite(est.occlusion) else 1.0
        score = float(est.score) if _finite(est.score) else 0.0
        return self._track(Estimate(self.A, mode, occ, score), 1e3 * (time.perf_counter() - t0))

    def _track(self, est: Estimate, ms: float) -> Track:
        return Track(center=apply(est.A, self.center0[None])[0], corners=apply(est.A, self.corners0),
                     pose=matrix_to_pose(est.A, self.center0), mode=est.mode, occlusion=est.occlusion,
                     score=est.score, ms=ms)

    def _init(self, frame: np.ndarray, roi) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _update(self, frame: np.ndarray) -> Estimate:  # pragma: no cover - abstract
        raise NotImplementedError
