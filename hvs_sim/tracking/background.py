"""Camera motion measured on the scene around the target, for the hybrid tracker's predict path.

While the target is hidden, the flags and wall around it are usually still in view. The target is
rigidly part of that surface, so its image motion is the surface's image motion. Each frame,
corners found in a recent frame are followed into the current one with pyramidal Lucas–Kanade
(OpenCV) and a similarity is fitted with RANSAC, which rejects points on the occluder; the
similarities are chained from the keyframe (the last frame the target was aligned in).
Chained over short hops rather than matched to the keyframe, because a person crossing close to
the camera sweeps over the view: nothing of the keyframe may stay visible, but frames a few steps
apart always share something. A similarity rather than a homography because the visible part can
be a narrow strip, from which a homography extrapolates badly to the hidden target.

What it cannot do: when the occluder fills the whole view there is nothing to measure, and the
hybrid tracker falls back on its motion predictor.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.errors import ConfigError


@dataclass(frozen=True)
class BackgroundConfig:
    max_points: int = 200
    min_distance: int = 6  # work px between corners
    quality: float = 0.01  # goodFeaturesToTrack quality level
    window: int = 15  # LK window (work px)
    levels: int = 3  # LK pyramid levels above the base
    ransac_px: float = 0.3  # inlier threshold (work px)
    min_inliers: int = 15  # fewer: no trustworthy motion this frame
    min_inlier_ratio: float = 0.3  # of the corners LK could follow
    max_lk_error: float = 12.0  # mean absolute grey difference of a followed LK window
    hop: int = 5  # frames between the two images a motion is measured from (see update)

    def __post_init__(self):
        if not isinstance(self.hop, int) or self.hop < 1:
            raise ConfigError(f"hop must be an int >= 1, got {self.hop!r}")
        if self.max_points < 8 or self.min_inliers < 4:
            raise ConfigError(f"background motion needs max_points >= 8 and min_inliers >= 4, "
                              f"got {self.max_points}, {self.min_inliers}")
        if not 0 < self.min_inlier_ratio <= 1:
            raise ConfigError(f"min_inlier_ratio must be in (0, 1], got {self.min_inlier_ratio}")


class BackgroundMotion:
    """Similarity keyframe → current frame of the scene in view (work pixels)."""

    def __init__(self, config: BackgroundConfig = BackgroundConfig()):
        self.config = config
        self.reset()

    @property
    def active(self) -> bool:
        return bool(self.chain)

    def reset(self) -> None:
        self.chain: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=self.config.hop)  # (frame, keyframe → frame)

    def start(self, key: np.ndarray) -> None:
        self.reset()
        self.chain.append((key, np.eye(3)))

    def step(self, src: np.ndarray, grey: np.ndarray) -> np.ndarray | None:
        """Similarity from `src` to `grey`, or None when the scene gives no trustworthy one."""
        c = self.config
        pts = cv2.goodFeaturesToTrack(src, c.max_points, c.quality, c.min_distance, blockSize=7)
        if pts is None or len(pts) < c.min_inliers:
            return None
        nxt, status, err = cv2.calcOpticalFlowPyrLK(
            src, grey, pts, None, winSize=(c.window, c.window), maxLevel=c.levels,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01))
        ok = (status[:, 0] == 1) & (err[:, 0] < c.max_lk_error) & np.all(np.isfinite(nxt[:, 0]), axis=1)
        if ok.sum() < c.min_inliers:
            return None
        S, mask = cv2.estimateAffinePartial2D(pts[ok], nxt[ok], method=cv2.RANSAC,
                                              ransacReprojThreshold=c.ransac_px, maxIters=500, refineIters=10)
        if S is None or not np.all(np.isfinite(S)):
            return None
        S = np.vstack([S, [0.0, 0.0, 1.0]])
        if int(mask.sum()) < max(c.min_inliers, c.min_inlier_ratio * ok.sum()):
            return None
        return S

    def update(self, grey: np.ndarray) -> np.ndarray | None:
        """Similarity keyframe → `grey`, or None this frame (the chain then waits at the last good frame).

        Measured from the frame `hop` steps back in the chain when it is there, else from the
        last one: a person standing almost still moves a fraction of a pixel per frame, within
        RANSAC's tolerance, but several pixels over a few frames, where RANSAC rejects them."""
        sources = list(self.chain)[:1] if len(self.chain) == self.config.hop else []
        sources += list(self.chain)[-1:]
        for src, M_src in sources:
            S = self.step(src, grey)
            if S is not None:
                M = S @ M_src
                self.chain.append((grey, M))
                return M
        return None
