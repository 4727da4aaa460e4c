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
hybrid tracker falls back on its motion predictor; the chain then starts again from the
predictor's estimate, and KeyframeAnchor (below) takes that error out once the wall shows again.
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
    # goodFeaturesToTrack quality level, relative to the strongest corner in view: flag corners
    # are far stronger than the wall's texture, and at 0.01 a few columns of wall beside a person
    # gave too few corners to measure (README, tracking benchmark)
    quality: float = 0.001
    window: int = 15  # LK window (work px)
    levels: int = 3  # LK pyramid levels above the base
    ransac_px: float = 0.3  # inlier threshold (work px)
    # fewer: no trustworthy motion this frame. Low because a person sweeping past the lens can leave
    # a handful of wall corners for a few frames; a wrong consensus is caught by the hybrid's gate
    min_inliers: int = 6
    min_inlier_ratio: float = 0.3  # of the corners LK could follow
    max_lk_error: float = 12.0  # mean absolute grey difference of a followed LK window
    hop: int = 5  # frames between the two images a motion is measured from (see update)
    # re-anchoring (KeyframeAnchor): aligned frames kept, spaced in time, and their corners
    keyframes: int = 5
    spacing: int = 10  # frames between kept keyframes (the newest is always the latest aligned frame)
    anchor_points: int = 150  # corners per keyframe
    max_fb_px: float = 0.5  # forward–backward LK disagreement above which a point is dropped (chain and anchor)

    def __post_init__(self):
        for name in ("hop", "keyframes", "spacing"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ConfigError(f"{name} must be an int >= 1, got {v!r}")
        if not (self.ransac_px > 0 and self.max_fb_px > 0 and self.anchor_points >= 8):
            raise ConfigError(f"need ransac_px > 0, max_fb_px > 0 and anchor_points >= 8, got "
                              f"{self.ransac_px}, {self.max_fb_px}, {self.anchor_points}")
        if self.max_points < 8 or self.min_inliers < 4:
            raise ConfigError(f"background motion needs max_points >= 8 and min_inliers >= 4, "
                              f"got {self.max_points}, {self.min_inliers}")
        if not 0 < self.min_inlier_ratio <= 1:
            raise ConfigError(f"min_inlier_ratio must be in (0, 1], got {self.min_inlier_ratio}")


def _lk_params(c: BackgroundConfig) -> dict:
    return {"winSize": (c.window, c.window), "maxLevel": c.levels,
            "criteria": (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01)}


def _lk_checked(src: np.ndarray, dst: np.ndarray, start: np.ndarray, c: BackgroundConfig
               ) -> tuple[np.ndarray, np.ndarray]:
    """Pyramidal LK of the points `start` (N×2, float32) from `src` into `dst`; returns where they
    went and which are trustworthy: followed both ways to within `max_fb_px`, with a small window
    error. The backward check drops points LK cannot follow consistently, which RANSAC over a
    few points could otherwise agree on; a person's edge that moves smoothly passes it (README)."""
    lk = {**_lk_params(c), "flags": cv2.OPTFLOW_USE_INITIAL_FLOW}
    nxt, st, err = cv2.calcOpticalFlowPyrLK(src, dst, start, start.copy(), **lk)
    back, st_b, _ = cv2.calcOpticalFlowPyrLK(dst, src, nxt, start.copy(), **lk)
    ok = ((st[:, 0] == 1) & (st_b[:, 0] == 1) & (err[:, 0] < c.max_lk_error)
          & (np.linalg.norm(back - start, axis=1) < c.max_fb_px) & np.all(np.isfinite(nxt), axis=1))
    return nxt, ok


def _trusted_similarity(src: np.ndarray, dst: np.ndarray, c: BackgroundConfig) -> np.ndarray | None:
    """RANSAC similarity src → dst (3×3), or None when too few points agree on it."""
    if len(src) < c.min_inliers:
        return None
    S, mask = cv2.estimateAffinePartial2D(src, dst, method=cv2.RANSAC, ransacReprojThreshold=c.ransac_px,
                                          maxIters=500, refineIters=10)
    if S is None or not np.all(np.isfinite(S)):
        return None
    if int(mask.sum()) < max(c.min_inliers, c.min_inlier_ratio * len(src)):
        return None
    return np.vstack([S, [0.0, 0.0, 1.0]])


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
        pts = pts[:, 0].astype(np.float32)
        nxt, ok = _lk_checked(src, grey, pts, c)
        return _trusted_similarity(pts[ok], nxt[ok], c)

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


@dataclass
class _Keyframe:
    image: np.ndarray  # grey, work pixels
    A: np.ndarray  # reference → this frame (work pixels)
    frame: int
    corners: np.ndarray | None = None  # found when first needed


class KeyframeAnchor:
    """Similarity reference → current frame measured against frames where the target was aligned.

    The chain in BackgroundMotion starts again from the motion predictor's estimate after frames
    with nothing to measure (a person filling the view), and carries that estimate's error to the
    end of the occlusion. Once the wall shows again, this measures the current frame against a
    few earlier aligned frames (spaced in time, since the one just before the occlusion often
    already has the person in front of the part of the wall that shows next), each warped first
    by the current estimate so that LK only finds what the estimate missed: a position with no
    error carried over."""

    def __init__(self, config: BackgroundConfig = BackgroundConfig()):
        self.config = config
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
        c = self.config
        none = (np.empty((0, 2), np.float32), np.empty((0, 2), np.float32))
        if k.corners is None:
            pts = cv2.goodFeaturesToTrack(k.image, c.anchor_points, c.quality, c.min_distance, blockSize=7)
            k.corners = none[0] if pts is None else pts[:, 0].astype(np.float32)
        to_ref = np.linalg.inv(k.A)  # keyframe → reference
        P = predicted @ to_ref  # keyframe → grey, as predicted
        h, w = grey.shape[:2]
        start = cv2.transform(k.corners[None], P[:2])[0] if len(k.corners) else none[0]
        inside = np.all((start >= 0) & (start < [w - 1, h - 1]), axis=1)
        ref, start = k.corners[inside], start[inside]
        if len(ref) < 4:
            return none
        warped = cv2.warpAffine(k.image, P[:2], (w, h), flags=cv2.INTER_LINEAR)
        nxt, ok = _lk_checked(warped, grey, start, c)
        if not ok.any():
            return none
        return cv2.transform(ref[ok][None], to_ref[:2])[0].astype(np.float32), nxt[ok]

    def update(self, grey: np.ndarray, predicted: np.ndarray) -> np.ndarray | None:
        """Similarity reference → `grey`, searched from `predicted`, or None when not trustworthy."""
        c = self.config
        pairs = [self._follow(k, grey, np.asarray(predicted, float)) for k in self.keys]
        if not pairs:
            return None
        return _trusted_similarity(np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs]), c)
