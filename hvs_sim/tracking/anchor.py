"""Absolute re-measurement of the target against frames where it was aligned (the hybrid tracker's re-anchoring).

The chain of hops in background.BackgroundMotion is relative: after frames with nothing to measure it starts again
from the predictor's estimate and carries that estimate's error on. Kept aligned keyframes measure the current frame
against the target's own past views instead, so that error is taken out once the wall shows again.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import cv2
import numpy as np

# the chain's corner, LK and RANSAC helpers (background.py), shared so that both measure the scene the same way
from hvs_sim.tracking.background import (
    CORNER_BLOCK_SIZE,
    BackgroundConfig,
    _lk_checked,
    _transform,
    _trusted_similarity,
)
from hvs_sim.tracking.hop_model import RANSAC_MAX_ITERS
from hvs_sim.tracking.warp import normalised_homography, warp_image

# KeyframeAnchor's plane (BackgroundConfig.anchor_plane): a keyframe's homography counts on at least this many inliers
# (within ANCHOR_PLANE_PX), spread over at least this share of the view's width and height. A similarity pooled over
# keyframes whose poses were each the target's alone found no consensus at all (0 inliers of ~120) once a hand-held
# camera had tilted a few degrees since them: away from the target the wall does not move as the target's similarity
ANCHOR_PLANE_MIN_INLIERS = 20
ANCHOR_PLANE_SPREAD = 0.4
ANCHOR_PLANE_PX = 0.5
# a keyframe seconds old is compared with a frame whose exposure has drifted by up to ±10 %: 12 grey levels of window
# error rejected nearly every corner of a bright wall (0 of 150 followed); the forward–backward check and the plane's
# RANSAC still judge each point
ANCHOR_MAX_LK_ERROR = 30.0


def _ransac_homography(src: np.ndarray, dst: np.ndarray, c: BackgroundConfig) -> np.ndarray | None:
    """RANSAC homography src → dst (3×3), or None when too few points agree on it."""
    if len(src) < max(c.min_inliers, 4):
        return None
    found, mask = cv2.findHomography(src, dst, cv2.RANSAC, c.ransac_px, maxIters=RANSAC_MAX_ITERS)
    H = normalised_homography(found)
    if H is None or int(mask.sum()) < max(c.min_inliers, c.min_inlier_ratio * len(src)):
        return None
    return H


@dataclass
class _Keyframe:
    image: np.ndarray  # grey, work pixels
    A: np.ndarray  # reference → this frame (work pixels)
    frame: int
    corners: np.ndarray | None = None  # found when first needed


class KeyframeAnchor:
    """Reference → current frame measured against frames where the target was aligned (a similarity, or a keyframe's
    plane with `anchor_plane`; a homography for a homography tracker).

    The chain in BackgroundMotion starts again from the motion predictor's estimate after frames
    with nothing to measure (a person filling the view), and carries that estimate's error to the
    end of the occlusion. Once the wall shows again, this measures the current frame against a
    few earlier aligned frames (spaced in time, since the one just before the occlusion often
    already has the person in front of the part of the wall that shows next), each warped first
    by the current estimate so that LK only finds what the estimate missed: a position with no
    error carried over."""

    def __init__(self, config: BackgroundConfig | None = None, model: str = "similarity"):
        # "homography" for a homography tracker: the kept keyframes' corners spread over the whole
        # planar wall, where a homography is exact and well constrained (unlike the chain's narrow strips)
        config = BackgroundConfig() if config is None else config
        self.config, self.model = config, model
        self.keys: deque[_Keyframe] = deque(maxlen=config.keyframes)

    def reset(self) -> None:
        self.keys.clear()

    def add(self, grey: np.ndarray, A: np.ndarray, frame: int) -> None:
        """Frame number `frame`, in which `A` (reference → frame) is known. The newest keyframe is
        replaced until it is `spacing` frames younger than the one before it, so the kept ones
        span the recent past and the newest is always the latest."""
        k = _Keyframe(grey, np.asarray(A, float), frame)
        if len(self.keys) > 1 and self.keys[-1].frame - self.keys[-2].frame < self.config.spacing:
            self.keys[-1] = k
        else:
            self.keys.append(k)

    def _follow(self, k: _Keyframe, grey: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Corners of `k` in reference coordinates and where LK finds them in `grey` (trustworthy ones only)."""
        src, dst = self._follow_raw(k, grey, predicted)
        return (_transform(src, np.linalg.inv(k.A)) if len(src) else src), dst

    def _plane(self, k: _Keyframe, grey: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray | None, int]:
        """Reference → `grey` through the homography keyframe → `grey` of k's own corners (ANCHOR_PLANE_*), and its
        inlier count; (None, 0) when they do not give a trustworthy one."""
        src, dst = self._follow_raw(k, grey, predicted)
        if len(src) < ANCHOR_PLANE_MIN_INLIERS:
            return None, 0
        found, mask = cv2.findHomography(src, dst, cv2.RANSAC, ANCHOR_PLANE_PX, maxIters=RANSAC_MAX_ITERS)
        H = normalised_homography(found)
        if H is None:
            return None, 0
        inl = mask[:, 0].astype(bool)
        n = int(inl.sum())
        h, w = grey.shape[:2]
        if n < max(ANCHOR_PLANE_MIN_INLIERS, self.config.min_inlier_ratio * len(src)) or \
                np.any(np.ptp(src[inl], axis=0) < ANCHOR_PLANE_SPREAD * np.array([w, h])):
            return None, 0
        return H @ k.A, n

    def _follow_raw(self, k: _Keyframe, grey: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Corners of `k` (its own pixels) and where LK finds them in `grey` (trustworthy ones only)."""
        c = self.config
        none = (np.empty((0, 2), np.float32), np.empty((0, 2), np.float32))
        if k.corners is None:
            pts = cv2.goodFeaturesToTrack(k.image, c.anchor_points, c.quality, c.min_distance, blockSize=CORNER_BLOCK_SIZE)
            k.corners = none[0] if pts is None else pts[:, 0].astype(np.float32)
        to_ref = np.linalg.inv(k.A)  # keyframe → reference
        P = predicted @ to_ref  # keyframe → grey, as predicted
        h, w = grey.shape[:2]
        start = _transform(k.corners, P) if len(k.corners) else none[0]
        inside = np.all((start >= 0) & (start < [w - 1, h - 1]), axis=1)
        ref, start = k.corners[inside], start[inside]
        if len(ref) < 4:
            return none
        warped = warp_image(k.image, P, (w, h), flags=cv2.INTER_LINEAR)
        nxt, ok = _lk_checked(warped, grey, start, replace(c, max_lk_error=ANCHOR_MAX_LK_ERROR))
        if not ok.any():
            return none
        return ref[ok], nxt[ok]

    def plane(self, grey: np.ndarray, predicted: np.ndarray) -> np.ndarray | None:
        """Reference → `grey` through the keyframe whose own homography has the most inliers (anchor_plane), or None."""
        if not self.config.anchor_plane:
            return None
        found = [self._plane(k, grey, np.asarray(predicted, float)) for k in self.keys]
        best = max(found, key=lambda f: f[1], default=(None, 0))
        return best[0]

    def update(self, grey: np.ndarray, predicted: np.ndarray) -> np.ndarray | None:
        """Reference → `grey` (as KeyframeAnchor), searched from `predicted`, or None when not trustworthy."""
        c = self.config
        plane = self.plane(grey, predicted)
        if plane is not None:
            return plane
        pairs = [self._follow(k, grey, np.asarray(predicted, float)) for k in self.keys]
        if not pairs:
            return None
        src, dst = np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])
        if self.model == "homography":
            return _ransac_homography(src, dst, c)
        return _trusted_similarity(src, dst, c)
