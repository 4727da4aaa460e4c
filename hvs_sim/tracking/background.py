"""Camera motion measured on the scene around the target, for the hybrid tracker's predict path.

While the target is hidden, the flags and wall around it are usually still in view. The target is rigidly part of that
surface, so its image motion is the surface's image motion. Each frame, corners found in a recent frame are followed
into the current one with pyramidal Lucas–Kanade (OpenCV) and a similarity is fitted with RANSAC, which rejects points
on the occluder; the similarities are chained from the keyframe (the last frame the target was aligned in). Chained over
short hops rather than matched to the keyframe, because a person crossing close to the camera sweeps over the view:
nothing of the keyframe may stay visible, but frames a few steps apart always share something. The consensus is found as
a similarity, because the visible part can be a narrow strip, from which a homography extrapolates badly to the hidden
target; where its inliers spread over the view, the hop is refitted on them as a homography (`homography`): a picture on
a wall moves as a plane, and a similarity chained through a hand-held camera's tilt drifted 2–4 px in 3 s where the
homography of the same wall points stayed within 0.5 px (docs/tuning.md). Under a hand-held camera's tilt a similarity
within RANSAC's 0.3 px often holds only part of the wall (one strip beside a coat), so the hop also looks for the plane
that contains the similarity's consensus among the followed points (`grow_plane`; not the occluder's: a homography bent
across a coat and a strip of wall fits both), and keeps it where a robust model-selection criterion (Torr's GRIC) says
the plane explains the points better than the similarity by more than its four extra parameters cost: in a scene of one
plane it takes in the rest of the wall; in a scene of several depths (a room, a floor, people) a homography that merely
bends to a few more points is not chosen.

The occluder is what stands in front of the target (`occluder_prior`): of two competing consensuses, one with corners on
the hidden target's box, where the other has almost none, is the occluder's (a partly hidden target's own visible
corners move with the wall, so then neither is ruled out). Without it a checked shirt standing over the target gave
every one of the strongest corners, and the chain followed the person's sway. Corners are also guaranteed in every part
of the view (`cell_corners`), so that a weakly textured wall still has some beside a strongly textured coat.

What it cannot do: when the occluder fills the whole view there is nothing to measure, and the hybrid tracker falls back
on its motion predictor; the chain then starts again from the predictor's estimate, and anchor.KeyframeAnchor takes that
error out once the wall shows again."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.hop_model import RANSAC_MAX_ITERS, hop_model, view_centre
from hvs_sim.tracking.occlusion import median_1d
from hvs_sim.tracking.warp import apply, is_affine
from hvs_sim.validate import check_flags, check_number


@dataclass(frozen=True)
class BackgroundConfig:
    max_points: int = 200
    min_distance: int = 6  # work px between corners
    # goodFeaturesToTrack quality level, relative to the strongest corner in view: flag corners
    # are far stronger than the wall's texture, and at 0.01 a few columns of wall beside a person
    # gave too few corners to measure (README, tracking benchmark)
    quality: float = 0.001
    window: int = 15  # LK window (work px)
    # LK pyramid levels above the base. Two instead of three cost a fifth less of the predict path, but on the
    # natural benchmark's pause sequences lost 1.6 points ≤ 2 px (README, hybrid speed)
    levels: int = 3
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
    competing: bool = True  # a second consensus competes with the first; the one moving as the scene did wins
    homography: bool = True  # a hop whose inliers spread over the view is refitted on them as a homography
    # ... and the similarity's consensus is grown into the plane that contains it where GRIC prefers that plane
    # (module docstring); False: the refit on the similarity's own inliers only
    grow_plane: bool = True
    # ... and a hop neither refits nor grows into a plane is refitted on its inliers as the camera's turn
    # (warp.fit_turn: a similarity after a rotation about the camera's centre, hop_model.TURN_FOCAL) instead of kept
    # a similarity
    turn: bool = True
    occluder_prior: bool = True  # a consensus on the hidden target is the occluder's (module docstring)
    # a hop whose consensus the caller refuses (the hybrid's gate: it jumps) offers the consensus among the points the
    # first did not hold: a coat sweeping in held 147 of 182 corners and moved 8 px a frame, and the wall beside it
    # was not measured until the coat stood still (photos' dev split, `long`); False: the first only
    runner_up: bool = True
    # at least this many corners in each of CELL_GRID × CELL_GRID parts of the view (at that part's own contrast);
    # 0: the strongest `max_points` of the whole view only, as before
    cell_corners: int = 6
    # re-anchoring: each keyframe's own corners give a homography keyframe → frame (the wall is a plane), which
    # carries that keyframe's aligned pose, tried on every unaligned frame; False (the default): only the pooled
    # similarity over all keyframes after predictor-only frames (KeyframeAnchor). Off because it has not earned its
    # place everywhere: on hand-held photos (one plane) it took the dev split's `hand` from 69.6 to 91.6 % of frames
    # within 2 px, but in the simulated scenes (a wall, a floor, people: not one plane) it replaced the finer chain of
    # hops under a partly covered target (bench track dev seeds 102-105, `partial`: 99.7 -> 97.5 % within 2 px)
    anchor_plane: bool = False
    # each frame measured from two frames of the chain, `hop` and `hop` − FUSE_NEARER frames back (with `hop` over 2),
    # and the two averaged where both are taken and agree at the hidden target's centre (FUSE_AGREE_PX): from one
    # frame `hop` back, the frames form `hop` interleaved chains, each with its own error, and the estimate jumped
    # between them by 1-3 px from frame to frame under a coat; each frame measured from two of them ties them together
    # (docs/results.md). Not from the frame before: a person
    # swaying slowly moves with the wall within RANSAC's 0.3 px over one frame (tracking benchmark, `partial`: within
    # 1 px 93.0 -> 85.2 %). False: from the frame `hop` back alone
    fuse_hops: bool = True

    def __post_init__(self):
        for name in ("hop", "keyframes", "spacing"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ConfigError(f"{name} must be an int >= 1, got {v!r}")
        if not (self.ransac_px > 0 and self.max_fb_px > 0 and self.anchor_points >= 8):
            raise ConfigError(f"need ransac_px > 0, max_fb_px > 0 and anchor_points >= 8, got "
                              f"{self.ransac_px}, {self.max_fb_px}, {self.anchor_points}")
        check_number("background cell_corners", self.cell_corners, 0, integer=True)
        check_flags(self, ("competing", "homography", "grow_plane", "turn", "occluder_prior", "runner_up",
                           "anchor_plane", "fuse_hops"))
        if self.max_points < 8 or self.min_inliers < 4:
            raise ConfigError(f"background motion needs max_points >= 8 and min_inliers >= 4, "
                              f"got {self.max_points}, {self.min_inliers}")
        check_number("background levels", self.levels, 0, integer=True)
        if not 0 < self.min_inlier_ratio <= 1:
            raise ConfigError(f"min_inlier_ratio must be in (0, 1], got {self.min_inlier_ratio}")


COMPETING_SHARE = 0.2  # a second consensus this large (of the first's inliers) competes with it
RANSAC_REFINE_ITERS = 10  # the similarity's refinement on its inliers
LK_MAX_ITERATIONS, LK_EPS = 30, 0.01  # pyramidal LK stopping rule per level (OpenCV's defaults)
CORNER_BLOCK_SIZE = 7  # goodFeaturesToTrack's structure-tensor window (work px)
CELL_GRID = 4  # BackgroundConfig.cell_corners: the view cut into 4 × 4 parts
HIDDEN_DILATE = 1.25  # the hidden target's box, grown about its centre: corners there are the occluder's
# of two consensuses, one with over OCCLUDER_SHARE of its points on the hidden target (a shirt over it: 8–25 %; the
# wall with a partly hidden target's visible corners: 5–8 %) is the occluder's where the
# other has almost none there (a partly hidden target's own visible corners move with the wall), OCCLUDER_MIN_OTHER
# points in all ...
OCCLUDER_SHARE = 0.1
OCCLUDER_CLEAR = 0.02
OCCLUDER_MIN_OTHER = 12
OCCLUDER_SPREAD = 0.5  # ... spread over half the corners' extent both ways (a strip of wall is not the wall) ...
# a target the occluder covers (OP_t at the estimate at least COVERED_OP, HybridState.hidden_share): the wall has no
# corners on its box (the box shrunk by COVERED_SHRINK about its centre, for an estimate a few px off), so a consensus
# moving COVERED_MIN_POINTS of them is the occluder's however large it is (a coat twice the view's size over the
# target: 5-9 % of its corners there, under OCCLUDER_SHARE), and the scene's motion is the consensus among the
# other points, or none
COVERED_OP = 0.8
# ... and a target with OP_t at most CLEAR_OP at the estimate is in view (a clear hand-held view reads up to ~0.15 from
# blur and noise): the corners on its box are its own and move with the scene, so the box says nothing of the occluder
CLEAR_OP = 0.15
COVERED_SHRINK = 0.8
COVERED_MIN_POINTS = 3
OCCLUDER_MISS_PX = 2.0  # ... and moving no more than this further from the scene's expected motion than the first
# BackgroundConfig.fuse_hops: the two hops' measurements are averaged where they agree this well (work px)
FUSE_AGREE_PX = 1.0
# ... the second measured from this many frames nearer than the long hop's start: 1 (the frame `hop` − 1 back) was
# chosen over the frame before, whose one-frame hop a slowly swaying person moves with (docs/tuning.md)
FUSE_NEARER = 1


def _lk_params(c: BackgroundConfig) -> dict:
    return {"winSize": (c.window, c.window), "maxLevel": c.levels,
            "criteria": (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, LK_MAX_ITERATIONS, LK_EPS)}


def _lk_checked(src: np.ndarray, dst: np.ndarray, start: np.ndarray, c: BackgroundConfig
               ) -> tuple[np.ndarray, np.ndarray]:
    """Pyramidal LK of the points `start` (N×2, float32) from `src` into `dst`; returns where they
    went and which are trustworthy: followed both ways to within `max_fb_px`, with a small window
    error. The backward check drops points LK cannot follow consistently, which RANSAC over a
    few points could otherwise agree on; a person's edge that moves smoothly passes it (README).
    Points the forward pass already failed are not followed back (LK follows each point on its own,
    so the others' answers are the same)."""
    lk = {**_lk_params(c), "flags": cv2.OPTFLOW_USE_INITIAL_FLOW}
    nxt, st, err = cv2.calcOpticalFlowPyrLK(src, dst, start, start.copy(), **lk)
    ok = (st[:, 0] == 1) & (err[:, 0] < c.max_lk_error) & np.all(np.isfinite(nxt), axis=1)
    if ok.any():
        there, home = nxt[ok], start[ok]
        back, st_b, _ = cv2.calcOpticalFlowPyrLK(dst, src, there, home.copy(), **lk)
        ok[ok] = (st_b[:, 0] == 1) & (np.linalg.norm(back - home, axis=1) < c.max_fb_px)
    return nxt, ok


def _ransac(src: np.ndarray, dst: np.ndarray, c: BackgroundConfig) -> tuple[np.ndarray | None, np.ndarray]:
    S, mask = cv2.estimateAffinePartial2D(src, dst, method=cv2.RANSAC, ransacReprojThreshold=c.ransac_px,
                                          maxIters=RANSAC_MAX_ITERS, refineIters=RANSAC_REFINE_ITERS)
    if S is None or not np.all(np.isfinite(S)):
        return None, np.zeros(len(src), bool)
    return np.vstack([S, [0.0, 0.0, 1.0]]), mask[:, 0].astype(bool)


def _consensus(src: np.ndarray, dst: np.ndarray, c: BackgroundConfig, expected: np.ndarray | None = None,
               hidden: np.ndarray | None = None, covered: bool = False
               ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """RANSAC similarity src → dst (3×3), its inliers and the points judged the occluder's (a consensus ruled out
    as the occluder's, the covered box's points), or None when too few points agree on it.

    A second consensus among the first one's outliers competes with it: a textured coat that fills
    half the view gives as many agreeing corners as the wall. With `hidden` (the hidden target's
    box in src, 4×2), the consensus gathered around it is the occluder's; otherwise, with `expected`
    (the displacement the scene's motion so far predicts at each point), the consensus whose motion
    is nearer the expected one wins."""
    none = None, np.zeros(len(src), bool), np.zeros(len(src), bool)
    if len(src) < c.min_inliers:
        return none
    S, inl = _ransac(src, dst, c)
    if S is None or int(inl.sum()) < max(c.min_inliers, c.min_inlier_ratio * len(src)):
        return none
    clear = np.zeros(len(src), bool)
    if covered and hidden is not None:
        on_box = _near(src, hidden, COVERED_SHRINK)
        if int((on_box & inl).sum()) >= COVERED_MIN_POINTS:  # the occluder's consensus (COVERED_OP)
            rest = np.flatnonzero(~inl & ~on_box)
            if len(rest) < c.min_inliers:
                return none
            S2, inl2 = _ransac(src[rest], dst[rest], c)
            if S2 is None or int(inl2.sum()) < max(c.min_inliers, OCCLUDER_MIN_OTHER):  # a 6-point strip's similarity
                return none  # missed the hidden target by 1.0-1.3 px a hop, the same way (docs/results.md)
            second = np.zeros(len(src), bool)
            second[rest[inl2]] = True
            return S2, second, inl | on_box
    if (expected is None and hidden is None) or (~inl).sum() < c.min_inliers:
        return S, inl, clear
    rest = np.flatnonzero(~inl)
    S2, inl2 = _ransac(src[rest], dst[rest], c)
    if S2 is None or inl2.sum() < c.min_inliers:
        return S, inl, clear
    second = np.zeros(len(src), bool)
    second[rest[inl2]] = True

    def miss(M):
        return _miss(M, src, expected)

    if hidden is not None:  # beside a hidden target any second consensus competes: the wall beside a coat can
        f1, f2 = (float(np.mean(_near(src[m], hidden))) for m in (inl, second))  # give far fewer corners
        if f1 > OCCLUDER_SHARE and f2 <= OCCLUDER_CLEAR and second.sum() >= OCCLUDER_MIN_OTHER and \
                np.all(np.ptp(src[second], axis=0) >= OCCLUDER_SPREAD * np.ptp(src, axis=0)) and (
                expected is None or miss(S2) <= miss(S) + OCCLUDER_MISS_PX):  # not a repeated texture's false match
            return S2, second, inl
        if f2 > OCCLUDER_SHARE and f1 <= OCCLUDER_CLEAR:
            return S, inl, second
    if expected is None or second.sum() < COMPETING_SHARE * inl.sum():
        return S, inl, clear
    return (S2, second, clear) if miss(S2) < miss(S) else (S, inl, clear)


def _miss(M: np.ndarray, src: np.ndarray, expected: np.ndarray) -> float:
    """How far the motion M is from the expected displacement at each point (median over the points)."""
    return median_1d(np.linalg.norm(apply(M, src) - src - expected, axis=1))


def _near(pts: np.ndarray, hidden: np.ndarray, dilate: float = HIDDEN_DILATE) -> np.ndarray:
    """Which points lie on the hidden target: in the bounding box of its box grown by `dilate` about its centre."""
    centre = hidden.mean(0)
    grown = centre + dilate * (hidden - centre)
    return np.all((pts >= grown.min(0)) & (pts <= grown.max(0)), axis=1)


def _trusted_similarity(src: np.ndarray, dst: np.ndarray, c: BackgroundConfig) -> np.ndarray | None:
    """RANSAC similarity src → dst (3×3), or None when too few points agree on it (_consensus)."""
    return _consensus(src, dst, c)[0]


def _corners(img: np.ndarray, c: BackgroundConfig, limit: int) -> np.ndarray | None:
    """Corners (N×2 float32) to follow: the `limit` strongest, and at least `cell_corners` in each part of the view
    that has any (at that part's own contrast)."""
    h, w = img.shape[:2]
    pts = cv2.goodFeaturesToTrack(img, limit, c.quality, c.min_distance, blockSize=CORNER_BLOCK_SIZE)
    pts = np.empty((0, 2), np.float32) if pts is None else pts[:, 0].astype(np.float32)
    if c.cell_corners:
        extra = []
        for i in range(CELL_GRID):
            for j in range(CELL_GRID):
                y0, y1, x0, x1 = i * h // CELL_GRID, (i + 1) * h // CELL_GRID, j * w // CELL_GRID, (j + 1) * w // CELL_GRID
                inside = (pts[:, 0] >= x0) & (pts[:, 0] < x1) & (pts[:, 1] >= y0) & (pts[:, 1] < y1)
                if inside.sum() >= c.cell_corners:
                    continue
                cell = cv2.goodFeaturesToTrack(np.ascontiguousarray(img[y0:y1, x0:x1]), c.cell_corners, c.quality,
                                               c.min_distance, blockSize=CORNER_BLOCK_SIZE)
                if cell is None:
                    continue
                cell = cell[:, 0].astype(np.float32) + np.float32([x0, y0])
                if inside.any():  # not those already found
                    near = np.linalg.norm(cell[:, None] - pts[inside][None], axis=2).min(1) < c.min_distance
                    cell = cell[~near]
                extra.append(cell)
        if extra:
            pts = np.concatenate([pts, *extra])
    return pts if len(pts) else None


def _transform(pts: np.ndarray, M: np.ndarray) -> np.ndarray:
    """float32 points (N, 2) through an affine or projective 3×3."""
    if not len(pts):
        return pts
    out = cv2.transform(pts[None], M[:2])[0] if is_affine(M) else cv2.perspectiveTransform(pts[None], M)[0]
    return out.astype(np.float32)


def _per_frame(S: np.ndarray, frames: int) -> np.ndarray:
    """The similarity that, applied `frames` times, gives S (its rotation, log-scale and translation shared out)."""
    if frames == 1:
        return S
    a, b = S[0, 0], S[1, 0]
    theta, scale = np.arctan2(b, a) / frames, np.hypot(a, b) ** (1.0 / frames)
    R = scale * np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    # t = (I + R + … + R^(n−1)) t1 → t1 = (Σ R^k)⁻¹ t
    acc = sum(np.linalg.matrix_power(R, k) for k in range(frames))
    V = np.eye(3)
    V[:2, :2] = R
    V[:2, 2] = np.linalg.solve(acc, S[:2, 2])
    return V


class BackgroundMotion:
    """Keyframe → current frame of the scene in view (work pixels): a similarity, or a homography where hops were
    refitted or grown into a plane."""

    def __init__(self, config: BackgroundConfig = BackgroundConfig()):
        self.config = config
        self.reset()

    @property
    def active(self) -> bool:
        return bool(self.chain)

    def reset(self, forget_motion: bool = False) -> None:
        """Drop the chain (it starts again at the next keyframe); the scene's last per-frame motion is
        kept unless `forget_motion` (a new target): it still tells the wall from a coat."""
        # (frame number, image, keyframe → image)
        self.chain: deque[tuple[int, np.ndarray, np.ndarray]] = deque(maxlen=self.config.hop)
        self._corner_cache: deque[tuple[np.ndarray, np.ndarray | None]] = deque(maxlen=self.config.hop + 1)
        self.frame = 0
        self.covered = False  # the hidden target is covered (COVERED_OP): set by the caller for each frame
        if forget_motion or not hasattr(self, "velocity"):
            self.velocity: np.ndarray | None = None  # the scene's last per-frame motion (similarity)
            self.velocity_age = 0.0  # frames from the middle of the hop it was measured over to the hop's end

    def start(self, key: np.ndarray) -> None:
        self.reset()
        self.chain.append((0, key, np.eye(3)))

    def step(self, src: np.ndarray, grey: np.ndarray, frames: int = 1, hidden: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray] | None:
        """The scene's motion from `src` to `grey` (`frames` apart) and its similarity, or None when the scene gives
        no trustworthy one. `hidden`: the hidden target's box in `src` (4×2), or None. `src`'s corners are kept for
        the array object (_corners_of): pass a new array for a new image, not a reused buffer."""
        return next(self._candidates(src, grey, frames, hidden), None)

    def _corners_of(self, src: np.ndarray) -> np.ndarray | None:
        """The corners to follow from `src` (_corners), found once per image: with `fuse_hops` each frame of the
        chain starts two hops."""
        for image, pts in self._corner_cache:
            if image is src:
                return pts
        pts = _corners(src, self.config, self.config.max_points)
        self._corner_cache.append((src, pts))
        return pts

    def _candidates(self, src: np.ndarray, grey: np.ndarray, frames: int, hidden: np.ndarray | None
                    ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """The hop's motions src → `grey` (each with its similarity), best first: the consensus `_consensus` chooses,
        then (BackgroundConfig.runner_up) the largest consensus among the points it did not hold, which a caller that
        refuses the first can take (`update`)."""
        c = self.config
        pts = self._corners_of(src)
        if pts is None or len(pts) < c.min_inliers:
            return
        nxt, ok = _lk_checked(src, grey, pts, c)
        expected = None
        if c.competing and self.velocity is not None:
            V = np.linalg.matrix_power(self.velocity, frames)
            expected = apply(V, pts[ok]) - pts[ok]
        p, q = pts[ok], nxt[ok]
        S, inl, occluder = _consensus(p, q, c, expected, hidden if c.occluder_prior and c.competing else None,
                                      self.covered and c.occluder_prior)
        if S is None:
            return
        yield (hop_model(S, inl, p, q, src.shape[:2], c, occluder) if c.homography else S), S
        if not c.runner_up or expected is None:
            return
        # the first was refused (a coat sweeping in, which holds most corners, jumps past the gate): the wall is among
        # the points it did not hold, and moves nearer the scene's expected motion than the first (a first refused
        # because the estimate had drifted is the wall, and the runner-up the coat)
        rest = np.flatnonzero(~inl)
        if len(rest) < c.min_inliers:
            return
        S2, inl2 = _ransac(p[rest], q[rest], c)
        if S2 is None or int(inl2.sum()) < OCCLUDER_MIN_OTHER or _miss(S2, p, expected) >= _miss(S, p, expected):
            return
        second = np.zeros(len(p), bool)
        second[rest[inl2]] = True
        if hidden is not None and _near(p[second], hidden).any():  # the wall has no corners on the hidden target
            return
        yield (hop_model(S2, second, p, q, src.shape[:2], c, inl) if c.homography else S2), S2  # the first: a coat's

    def update(self, grey: np.ndarray, hidden: np.ndarray | None = None,
               accept: Callable[[np.ndarray], bool] | None = None) -> np.ndarray | None:
        """Keyframe → `grey` (a similarity, or a homography where hops were refitted), or None this frame (the chain
        then waits at the last good frame). `hidden`: the hidden target's box (4×2, work px), or None. `accept`: the
        caller's judgement of a measurement (keyframe → `grey`); one it refuses is not chained, and the next hop is
        tried.

        Measured from the frame `hop` steps back in the chain when it is there, else from the
        last one: a person standing almost still moves a fraction of a pixel per frame, within
        RANSAC's tolerance, but several pixels over a few frames, where RANSAC rejects them. Where the long hop's
        consensus is refused (a coat sweeping in gives the only one of the 5-frame hop), the short one is tried. A long
        hop taken is averaged with the hop from the frame after its start (`fuse_hops`, _fused)."""
        self.frame += 1
        sources = list(self.chain)[:1] if len(self.chain) == self.config.hop > 1 else []
        sources += list(self.chain)[-1:]
        for k, src, M_src in sources:
            for model, S in self._candidates(src, grey, self.frame - k, hidden):
                M = model @ M_src
                if accept is not None and not accept(M):
                    continue
                if self.config.fuse_hops and len(sources) == 2 and k == sources[0][0] and \
                        self.config.hop - FUSE_NEARER > 1:
                    M = self._fused(M, self.chain[FUSE_NEARER], grey, hidden, accept)
                self.chain.append((self.frame, grey, M))
                self.velocity, self.velocity_age = _per_frame(S, self.frame - k), (self.frame - k - 1) / 2
                return M
        return None

    def _fused(self, M: np.ndarray, other: tuple[int, np.ndarray, np.ndarray], grey: np.ndarray,
               hidden: np.ndarray | None, accept: Callable[[np.ndarray], bool] | None) -> np.ndarray:
        """The long hop's keyframe → `grey` (M) averaged with the one measured from the chain's `other` frame, where
        that is measured, taken by the caller and within FUSE_AGREE_PX of M at the hidden target (the view's centre
        without one); else M (BackgroundConfig.fuse_hops)."""
        k, src, M_src = other
        found = next(self._candidates(src, grey, self.frame - k, hidden), None)
        if found is None:
            return M
        M_short = found[0] @ M_src
        if accept is not None and not accept(M_short):
            return M
        at = (hidden.mean(0) if hidden is not None else view_centre(grey.shape[:2]))[None]
        if np.linalg.norm(apply(M_short @ np.linalg.inv(M), at) - at) > FUSE_AGREE_PX:
            return M
        return 0.5 * (M / M[2, 2] + M_short / M_short[2, 2])

    def peek(self, key: np.ndarray, grey: np.ndarray, hidden: np.ndarray | None = None) -> np.ndarray | None:
        """What `update` would answer for `grey` from the chain's last frame (`key` where the chain has not started),
        leaving the chain as it was: for a check on a frame that may still be aligned. None where the scene gives
        no trustworthy motion."""
        k, src, M_src = self.chain[-1] if self.chain else (0, key, np.eye(3))
        measured = self.step(src, grey, max(self.frame + 1 - k, 1), hidden)
        return None if measured is None else measured[0] @ M_src
