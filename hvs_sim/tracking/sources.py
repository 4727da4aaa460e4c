"""Motion sources of the hybrid tracker's predict path: each proposes a pose for a frame in which the
target could not be aligned, or nothing. The hybrid tries them in a fixed order and takes the first
proposal (ViSP composes its template trackers the same way: parts with one interface).

- `KeyframeAnchorSource`: after frames that only the predictor moved, the target measured against
  earlier aligned keyframes (anchor.KeyframeAnchor) — an absolute measurement.
- `SceneMotionSource`: the last aligned (or re-anchored) pose moved by the motion of the surroundings since
  then (a similarity, or the plane that holds it) (background.BackgroundMotion) — a relative measurement.
- `PredictorSource`: the motion predictor's extrapolation (GRU, constant velocity, hold), bounded:
  after `max_frames` unmeasured frames it proposes `lost`.

Sources read the tracker's `HybridState` and never change it; `HybridState`'s transitions (below)
tell them what happened through `on_aligned`, `on_measured` and `on_predicted`.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from hvs_sim.tracking.anchor import KeyframeAnchor
from hvs_sim.tracking.background import CLEAR_OP, COVERED_OP, BackgroundConfig, BackgroundMotion
from hvs_sim.tracking.base import Mode
from hvs_sim.tracking.predictors import MotionPredictor
from hvs_sim.tracking.warp import apply, in_view_share, matrix_to_pose, translate

if TYPE_CHECKING:  # pragma: no cover
    from hvs_sim.tracking.aligner import Aligner


class Kind:
    """What a proposal is, which decides the state transition it causes."""

    ABSOLUTE = "absolute"  # measured against the template's own past views: the chain restarts here
    RELATIVE = "relative"  # measured relative to the last anchored pose: the chain goes on
    PREDICTED = "predicted"  # extrapolated: nothing measured


@dataclass(frozen=True)
class Proposal:
    A: np.ndarray  # full-resolution frame-from-template warp
    kind: str  # Kind.*
    mode: Mode  # the mode the Track reports
    source: str  # the proposing source's name


class MotionSource(Protocol):
    name: str

    def reset(self, state: HybridState) -> None: ...

    def propose(self, work: np.ndarray, state: HybridState) -> Proposal | None: ...

    def on_aligned(self, work: np.ndarray, state: HybridState) -> None: ...

    def on_measured(self, work: np.ndarray, state: HybridState, proposal: Proposal) -> None: ...

    def on_predicted(self, work: np.ndarray, state: HybridState) -> None: ...


def _translation(A: np.ndarray, center0: np.ndarray) -> np.ndarray:
    return matrix_to_pose(A, center0)[:2]


ANCHOR_DRIFT_PX = 0.5  # px a frame the scene's chain may have drifted since the last alignment (KeyframeAnchorSource)
# SceneMotionSource: the scene's motion continues the last measured position at most this many frames old (a hand-held
# view's speed changes within a few frames) ...
MEASURED_VELOCITY_GAP = 3
CONTINUE_MIN_SPEED = 0.5  # ... and from half the gate a frame (a fraction of background_gate_px)
# ... and its bound widens by the largest change of the target's per-frame motion over this many of the last
# consecutive alignments, beyond the half of the gate left for it (HybridConfig.background_gate_sway, on_aligned)
SWAY_MEASUREMENTS = 5
# the quick hop (SceneMotionSource.quick_peek): pyramid levels of its LK, one frame's motion being small
QUICK_LEVELS = 2
# a target taken for covered (OP_t at the estimate at least background.COVERED_OP) stays so until OP_t falls under
# this: under a coat OP_t read 0.80-0.82 frame after frame and dipped to 0.797, and on those frames the coat's
# consensus, moving with the view one way but not the other, was chained (photos' dev split, `long` aero, seed 7)
COVERED_HOLD_OP = 0.6
# covered_in_view: below this share of the target's box in the view, its OP_t stands as measured
IN_VIEW_MIN = 0.05


def covered_in_view(op: float, in_view: float) -> float:
    """The share of the target's pixels in view that something covers, from OP_t (`op`), which counts its pixels
    outside the frame as covered too, and the share of its box in view. A target leaving the view is not hidden behind
    anything: taken for covered, the wall's consensus, holding the corners of the target's part still in view, was
    ruled out as the occluder's and a 13-corner strip chained instead (photos' dev split, a `clear` sequence). OP_t
    itself where almost nothing of the target is in view (IN_VIEW_MIN)."""
    if in_view <= IN_VIEW_MIN:
        return op
    return min(max((op - (1.0 - in_view)) / in_view, 0.0), 1.0)


class KeyframeAnchorSource:
    """Absolute re-measurement after predictor-only frames; its jump is bounded by the predictor's
    possible drift (`gate_px` per unmeasured frame)."""

    name = "keyframe_anchor"

    def __init__(self, aligner: Aligner, config: BackgroundConfig, gate_px: float):
        self.aligner, self.gate_px = aligner, gate_px
        self.anchor = KeyframeAnchor(config, aligner.config.warp)

    def reset(self, state: HybridState) -> None:
        self.anchor.reset()
        self.anchor.add(state.keyframe[0], self.aligner.to_work(state.keyframe[1]), 0)

    def propose(self, work, state):
        # after predictor-only frames: the keyframes' planes, else their pooled similarity; on the other unaligned
        # frames the planes alone (BackgroundConfig.anchor_plane): an absolute measurement where the chain of hops
        # drifts (2-10 px over a 3 s occlusion of a hand-held view, handheld photos' dev split)
        if state.drift_run == 0 and not self.anchor.config.anchor_plane:
            return None
        predicted = self.aligner.to_work(state.A)
        M = self.anchor.plane(work, predicted) if state.drift_run == 0 else self.anchor.update(work, predicted)
        if M is None:
            return None
        A = self.aligner.to_full(M)
        moved = np.linalg.norm(_translation(A, state.center0) - _translation(state.A, state.center0))
        # the predictor's drift bounds the jump, and the chain's (ANCHOR_DRIFT_PX a frame since the last alignment)
        if moved > self.gate_px * (1 + state.drift_run) + ANCHOR_DRIFT_PX * state.since_aligned:
            return None
        return Proposal(A, Kind.ABSOLUTE, Mode.PREDICT, self.name)

    def on_aligned(self, work, state):
        self.anchor.add(work, self.aligner.to_work(state.A), state.frame_index)

    def on_measured(self, work, state, proposal):
        pass

    def on_predicted(self, work, state):
        pass


class SceneMotionSource:
    """The pose at the chain's start moved by the scene's motion since then. A person
    filling most of the view can out-vote the scene in RANSAC; a wrong consensus jumps far more than
    a hand-held or servoed camera moves between frames, so each hop's measurement is refused past `gate_px` per
    frame since the last measurement (`_passes`, inside BackgroundMotion.update, which then tries the shorter hop),
    both from the estimate and from where the scene's measured motion carries the last measured position
    (`continues`; a view that sweeps faster than `gate_px` a frame is not a jump).

    Where the surroundings give nothing the gate takes, the estimate is carried on by the scene's last measured
    per-frame motion for up to `inertia` frames (a guess, as the predictor's), before the predictor guesses.

    The chain starts at the last aligned or re-anchored frame. A frame the scene cannot measure (a
    coat sweeps past the lens) does not end it: for up to `patience` such frames in a row the next
    measurement still comes from the chain's last good frame, so a one-frame guess of the predictor
    is not carried on. Past that the chain starts again from the predictor's estimate."""

    name = "scene_motion"

    def __init__(self, aligner: Aligner, config: BackgroundConfig, gate_px: float, continues: bool = True,
                 inertia: int = 0, widen: bool = True):
        self.aligner, self.gate_px, self.continues, self.inertia = aligner, gate_px, continues, inertia
        self.widen = widen  # HybridConfig.background_gate_sway
        self.patience = config.hop
        self.motion = BackgroundMotion(config)
        # the strongest corners only, a similarity, fewer levels: a check on every aligned frame (quick_peek)
        self.quick = BackgroundMotion(replace(config, levels=QUICK_LEVELS, homography=False, cell_corners=0))

    def reset(self, state):
        self.motion.reset(forget_motion=True)
        self.last_aligned: tuple[int, np.ndarray] | None = None
        self.key = state.keyframe  # (work image, full-res warp) where the chain starts
        # the target's last measured pose (frame index, full-res warp): aligned, re-anchored or moved by the
        # surroundings, never predicted; the scene's motion continues it (_passes)
        self._step: np.ndarray | None = None  # the target's motion between the last two alignments (on_aligned)
        self._sways: deque[float] = deque(maxlen=SWAY_MEASUREMENTS)
        self._covered = False  # the target is taken for covered (COVERED_OP, COVERED_HOLD_OP)
        self.last_measured: tuple[int, np.ndarray] = (state.frame_index, state.A.copy())

    def _measured_at(self, state) -> None:
        self.last_measured = (state.frame_index, state.A.copy())

    def _continued(self, state) -> np.ndarray | None:
        """Where the scene's last per-frame motion (BackgroundMotion.velocity, measured over a hop) carries the last
        measured position on to this frame, or None without a recent one (MEASURED_VELOCITY_GAP). Not the velocity of
        the last two measured positions: they come from different interleaved chains of hops, which can differ by
        2-3 px, and that noise refused the correct measurements of a view sweeping 6 px a frame (dev split, `long`)."""
        f1, A1 = self.last_measured
        n, V = state.frame_index - f1, self.motion.velocity
        if V is None or n > MEASURED_VELOCITY_GAP:
            return None
        t1, t = (_translation(A, state.center0) for A in (A1, self._carried(A1, V, n)))
        # slower than half the gate a frame, the estimate's own bound already leaves half of it for the view's
        # acceleration; a continuation would only widen it towards a slowly swaying person (bench track dev seed 102,
        # `partial`: a 5 px jump of a person's consensus let in along a 1.3 px/frame drift)
        if np.linalg.norm(t - t1) < CONTINUE_MIN_SPEED * self.gate_px * max(n, 1):
            return None
        return t

    def measure(self, work, state: HybridState, peek: bool = False, gated: bool = False) -> np.ndarray | None:
        """Where the surroundings' motion since the chain's start puts the target (full-res warp); None when the
        surroundings cannot be measured, or (`gated`) when every hop's measurement jumps (`_passes`), which is then
        not chained. The target's box at the current estimate is where the surroundings are not
        (background.BackgroundConfig.occluder_prior). `peek`: measured in one hop from the chain's last good
        frame, the chain left as it was (BackgroundMotion.peek), for a check on a frame that may still be aligned
        (HybridTracker._verified)."""
        key_work, A_key = self.key
        # a target in view (CLEAR_OP) is no occluder's: its box's corners are its own and move with the scene
        box = apply(self.aligner.S @ state.A, state.corners0)
        covered = covered_in_view(state.hidden_share, in_view_share(box, work.shape[:2]))
        hidden = box if covered > CLEAR_OP else None
        self._covered = covered >= (COVERED_HOLD_OP if self._covered else COVERED_OP)
        self.motion.covered = self._covered
        al = self.aligner

        def full(M: np.ndarray) -> np.ndarray:
            return al.S_inv @ M @ al.S @ A_key  # (keyframe → this frame, full-res) ∘ keyframe warp

        if peek:
            M = self.motion.peek(key_work, work, hidden)
        else:
            if not self.motion.active:
                self.motion.start(key_work)
            M = self.motion.update(work, hidden, accept=(lambda M: self._passes(full(M), state)) if gated else None)
        return None if M is None else full(M)

    def quick_peek(self, work) -> np.ndarray | None:
        """Where the scene's motion since the chain's start puts the target (full-res warp), in one hop of the scene in
        view: a similarity from the strongest corners, at a fraction of `measure`'s cost (no corners per part of the
        view, no plane refit, one pyramid level less), for a check on the frame after each alignment (the chain's
        start; HybridTracker._pulled). None where the scene gives no trustworthy motion."""
        key_work, A_key = self.key
        found = self.quick.step(key_work, work)
        return None if found is None else self.aligner.S_inv @ found[0] @ self.aligner.S @ A_key

    def _passes(self, A: np.ndarray, state: HybridState) -> bool:
        """Whether a measurement of the surroundings moves the target no further than the view can move: a consensus
        that jumps is the occluder's. Judged from the estimate, and from where the scene's measured motion carries the
        last measured position (_continued; a view sweeping 5-7 px a frame, hand-held at 10 fps: from the estimate
        alone every correct measurement was refused, the estimate fell behind and the chain was restarted from it)."""
        t = _translation(A, state.center0)
        # the gate leaves half of itself for the view's acceleration (CONTINUE_MIN_SPEED); a sway beyond that widens it,
        # from the estimate too: after a re-anchoring the scene's last motion can be stale, and no continuation offered.
        # It widens for as many frames as the view's motion went unmeasured: since the last measurement, and since the
        # middle of the hop the scene's velocity was measured over (velocity_age; a view under half the gate a frame
        # is judged from the estimate, which stands for that velocity). A 5-frame hop at 10 fps is half a second, in
        # which a hand-held view's motion turned by up to 8 px a frame (photos' dev split)
        sway = max(self._sways, default=0.0) if self.widen else 0.0
        unmeasured = max(state.frame_index - self.last_measured[0], 1) + self.motion.velocity_age
        excess = max(sway - CONTINUE_MIN_SPEED * self.gate_px, 0.0) * unmeasured
        bound = self.gate_px * (1 + state.predict_run) + excess
        if np.linalg.norm(t - _translation(state.A, state.center0)) <= bound:
            return True
        continued = self._continued(state) if self.continues else None
        return continued is not None and bool(np.linalg.norm(t - continued) <= bound)

    def propose(self, work, state):
        A = self.measure(work, state, gated=True)
        if A is not None:
            return Proposal(A, Kind.RELATIVE, Mode.PREDICT, self.name)
        V = self.motion.velocity
        if V is None or state.predict_run >= self.inertia:
            return None
        # nothing the gate takes: for up to `inertia` frames a guess, the estimate carried on by the scene's last
        # measured per-frame motion (the camera's inertia), before the predictor's
        return Proposal(self._carried(state.A, V, 1), Kind.PREDICTED, Mode.PREDICT, self.name)

    def _carried(self, A: np.ndarray, V: np.ndarray, frames: int) -> np.ndarray:
        """The full-res pose A carried on `frames` frames by the scene's per-frame motion V (work px)."""
        al = self.aligner
        return al.S_inv @ np.linalg.matrix_power(V, frames) @ al.S @ A

    def on_aligned(self, work, state):
        self.motion.reset()  # the chain starts again from the new keyframe
        self._covered = False
        self.key = state.keyframe
        # the target is part of the scene: its frame-to-frame motion is the scene's, which tells the
        # wall's consensus from a coat's once the target is hidden (BackgroundMotion.velocity)
        A_work = self.aligner.to_work(state.A)
        if self.last_aligned is not None and self.last_aligned[0] == state.frame_index - 1:
            self.motion.velocity = A_work @ np.linalg.inv(self.last_aligned[1])
            self.motion.velocity_age = 0.0  # measured over one frame
            # how much the target's per-frame motion changed between consecutive alignments (px): the continuation's
            # own error a frame (_passes). A hand-held view's sway changed it by 1-2 px at 30 fps (the photos' dev
            # split), by 4-6 px at 10 fps. Not from the surroundings' hops: under a coat their noise read 2-4 px
            step = _translation(state.A, state.center0) - _translation(self.last_measured[1], state.center0)
            if self._step is not None:
                self._sways.append(float(np.linalg.norm(step - self._step)))
            self._step = step
        else:
            self._step = None
        self.last_aligned = (state.frame_index, A_work)
        self._measured_at(state)

    def on_measured(self, work, state, proposal):
        self._measured_at(state)
        if proposal.kind == Kind.ABSOLUTE:
            self.motion.reset()
            self.key = state.keyframe

    def on_predicted(self, work, state):
        if state.predict_run > self.patience:  # restart the scene's chain here, from this estimate
            self.motion.reset()
            self.key = (work, state.A)


class PredictorSource:
    """The motion predictor: it sees every confident translation and extrapolates the rest. A frame another source
    guessed (the scene's inertia, `lost`) joins its rollout as the estimate that frame ended with, so that its next
    prediction is one frame past the last estimate: without, after 5 inertia frames the GRU predicted the frame after
    the last measured one and threw the estimate 8-10 px back (photos' dev split, `long`)."""

    name = "predictor"

    def __init__(self, predictor: MotionPredictor, max_frames: int):
        self.predictor, self.max_frames = predictor, max_frames
        self._rolled = False  # this frame's estimate is already the predictor's own rollout

    def reset(self, state):
        self.predictor.reset()
        self.predictor.observe(_translation(state.A, state.center0))
        self._rolled = False

    def propose(self, work, state):
        if state.predict_run + 1 > self.max_frames:
            return Proposal(state.A, Kind.PREDICTED, Mode.LOST, self.name)
        # the target's centre moved to the prediction, its shape (θ, s, perspective) held
        A = translate(state.A, self.predictor.predict() - _translation(state.A, state.center0))
        self._rolled = True
        return Proposal(A, Kind.PREDICTED, Mode.PREDICT, self.name)

    def on_aligned(self, work, state):
        self.predictor.observe(_translation(state.A, state.center0))

    def on_measured(self, work, state, proposal):
        self.predictor.observe(_translation(state.A, state.center0))

    def on_predicted(self, work, state):
        if not self._rolled:
            self.predictor.carry(_translation(state.A, state.center0))
        self._rolled = False


@dataclass
class HybridState:
    """What changes from frame to frame. Changed only by the four transitions below, each of which
    tells every motion source what happened."""

    center0: np.ndarray  # template centre at init (full-res px)
    corners0: np.ndarray  # the template's corners at init (4×2, full-res px)
    A: np.ndarray  # the current estimate (full-res frame-from-template)
    keyframe: tuple[np.ndarray, np.ndarray]  # (work image, full-res warp) of the last aligned or re-anchored frame
    frame_index: int = 0
    predict_run: int = 0  # consecutive frames with neither an alignment nor a measurement
    drift_run: int = 0  # frames the predictor alone has moved the estimate since it was last anchored
    since_aligned: int = 0  # frames since the target was last aligned
    guessed: int = 0  # ... of which the predictor moved the estimate (or it was lost): not measured on the frames
    # the estimate at the last alignment: its θ and s were measured on the target itself, unlike a surroundings'
    # measurement since, which an occluder covering them can skew (Aligner.align's `aligned`)
    aligned_A: np.ndarray | None = None
    # a far re-acquisition awaiting confirmation: its offset from the estimate, and on how many
    # consecutive frames it was seen
    jump: np.ndarray | None = None
    jump_frames: int = 0
    thumb: np.ndarray | None = None  # the last frame's thumbnail (HybridTracker's cut test)
    after_cut: bool = False  # a scene cut was seen and the target not aligned since: lost
    # OP_t at the estimate on this frame (background.COVERED_OP, CLEAR_OP): from the match when it searched there, so
    # that the checks of an alignment see it too, else measured before the motion sources move the estimate
    hidden_share: float = 0.0
    is_lost: bool = False  # the last frame was `lost` (nothing says where the target is until it is aligned again)
    # the estimate comes from this tracker's own alignments and measurements of the scene, not from a pose given from
    # outside (Tracker.seed); with few predictor frames since (drift_run) it is the surroundings' (HybridTracker._verified)
    scene_held: bool = True

    def saw(self, thumb: np.ndarray | None) -> float:
        """This frame's thumbnail replaces the last one; returns how the two correlate (1: one shot, ~0: a cut; 1 when
        either frame had nothing to compare)."""
        ncc = 1.0 if self.thumb is None or thumb is None else float(thumb @ self.thumb)
        self.thumb = thumb
        return ncc

    def jump_seen(self, offset: np.ndarray | None, tolerance_px: float) -> int:
        """Record this frame's far re-acquisition candidate (None: there is none); returns on how
        many consecutive frames it has been seen, agreeing within `tolerance_px`."""
        if offset is None:
            self.jump, self.jump_frames = None, 0
            return 0
        agrees = self.jump is not None and np.linalg.norm(offset - self.jump) <= tolerance_px
        self.jump, self.jump_frames = offset, (self.jump_frames + 1 if agrees else 1)
        return self.jump_frames

    @property
    def measured_only(self) -> bool:
        """Whether only this tracker's measurements (alignments, re-anchoring, the surroundings) moved the estimate
        since it was last anchored: no predictor guess, no pose seeded from outside."""
        return self.drift_run == 0 and self.scene_held

    def departs_in_scale(self, A: np.ndarray, step: float, window: int) -> bool:
        """Whether A's scale departs by over the share `step` from the estimate's, where the surroundings alone carried
        the estimate (`measured_only`) for 1 to `window` - 1 frames since an alignment (HybridConfig.carried_scale_step;
        False with `step` 0). Not later: over a long gap an occluder over the surroundings can skew their scale."""
        if step <= 0 or not (1 <= self.since_aligned < window and self.measured_only):
            return False
        return bool(abs(matrix_to_pose(A, self.center0)[3] / matrix_to_pose(self.A, self.center0)[3] - 1) > step)

    def drifted_frames(self, lookalike: bool) -> int:
        """Frames since the last alignment over which the estimate may have drifted (HybridConfig.reacquire_drift_px
        each): with a look-alike in view only those the predictor guessed (HybridConfig.lookalike_drift)."""
        return self.guessed if lookalike else self.since_aligned

    def aligned(self, work: np.ndarray, A: np.ndarray, sources: list[MotionSource]) -> None:
        self.A = self.aligned_A = A
        self.predict_run = self.drift_run = self.since_aligned = self.guessed = 0
        self.jump, self.jump_frames = None, 0
        self.after_cut = self.is_lost = False
        self.scene_held = True
        self.keyframe = (work, A)
        for s in sources:
            s.on_aligned(work, self)

    def measured(self, work: np.ndarray, proposal: Proposal, sources: list[MotionSource]) -> None:
        self.A = proposal.A
        self.predict_run = 0
        self.is_lost = False
        self.after_cut = self.after_cut and proposal.kind != Kind.ABSOLUTE  # the old view, found again
        self.since_aligned += 1
        if proposal.kind == Kind.ABSOLUTE:  # the chain goes on from here
            self.drift_run = 0
            self.scene_held = True
            self.keyframe = (work, proposal.A)
        for s in sources:
            s.on_measured(work, self, proposal)

    def predicted(self, work: np.ndarray, A: np.ndarray, sources: list[MotionSource]) -> None:
        self.A = A
        self.is_lost = False
        self.predict_run += 1
        self.drift_run += 1
        self.since_aligned += 1
        self.guessed += 1
        for s in sources:
            s.on_predicted(work, self)

    def lost(self, work: np.ndarray, sources: list[MotionSource], cut: bool = False) -> None:
        """Nothing trustworthy: the estimate stays where it is (after a scene cut, until the next alignment)."""
        self.after_cut = self.after_cut or cut
        self.predicted(work, self.A, sources)
        self.is_lost = True
