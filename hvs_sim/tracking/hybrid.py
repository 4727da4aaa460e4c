"""The paper's hybrid tracker: global match → occlusion gate → deep LK + residual, or motion prediction.

Per frame: NCC over the whole frame gives a coarse centre and a score; OP_t is measured on the patch at that centre
and on the patch at the current estimate, and the better of the two is kept (see DeepLKTracker.coarse). If OP_t < gate
(40 %) and the match score ≥ 0.6 (or, with `continuity`, the seed is the current estimate) the frame is aligned
(feature LK, then the residual regressor) and its translation joins the predictor's history; otherwise the predictor
(GRU by default) extrapolates the translation, holding θ and s. With `gate_after_alignment` (a change to the paper, on
by default) a confident seed whose OP_t fails the gate is aligned anyway, and OP_t at the aligned pose decides: a seed
a few pixels off reads its misalignment as occlusion. Re-acquisition is automatic: the global match runs every frame,
so the first frame that passes the gate is aligned again.

Two changes to the paper in the predict path, both on by default and both measured (README, tracking benchmark;
`background=False, colour_occlusion=False` is the paper's hybrid as published):
- Predicting from the scene around the target (`background`, background.py): while the target is hidden the wall
  around it usually is not, so the predict path moves the last aligned pose by the surroundings' motion since then, a
  measurement of the camera's motion where the GRU only extrapolates it. The GRU takes over where the surroundings give
  no trustworthy motion (a person filling the view); once the wall shows again the frame is measured against earlier
  aligned keyframes (`reanchor`), not chained on from the predictor's guess.
- OP_t over colour channels (`colour_occlusion`, occlusion.py): grey OP_t read a flag half under a brown sleeve clear.

Built from parts (ViSP-style composition rather than inheritance): an `Aligner` (global match, feature LK, residual),
the OP_t gate, and motion sources tried in order on frames that are not aligned (sources.py: keyframe anchor → scene
motion → predictor). `HybridState` holds everything that changes from frame to frame, and its four transitions —
aligned, measured, predicted, lost — are the only way it changes.

A re-acquisition (after `lost`, a cut, or REACQUIRE_AFTER frames without an alignment) must pass several checks, not
the NCC score alone: the whole aligned patch's NCC with the template within APPEARANCE_SLACK of this track's own
confident alignments; and either a place the measured surroundings agree with, or a unique match (no look-alike beyond
half the template's side, which also catches a kerb's look-alike along it) seen at one place on `reacquire_frames`
consecutive frames, or at once where the ring of picture around it is the template's view's and the estimate's is not
(`context_check`, evidence.py: the estimate went wrong). An unrelated shot's facade that scores 0.6–0.7 is refused; so
is a look-alike 35 px along a weakly textured target after many predicted frames, which the predictor's growing bound
used to take in. Every `lost` episode says why in the tracker's notes (`hvs-sim track` prints them).

The extrapolating predictor is bounded: after `max_predict_frames` consecutive frames with neither an alignment nor a
background measurement (default 45, 1.5 s at 30 Hz) the mode becomes "lost" and the estimate stops moving until
re-acquisition. A scene cut (`cut_ncc`) and `max_unaligned_frames` without an alignment also end in "lost", whatever
the surroundings say; so does `max_predict_frames` without an alignment while `auto` has not yet decided the target's
motion (a target that moves or changes shape is not where its surroundings put it: its box would freeze there).

All of the above takes the target to be fixed in the scene (`target_motion="static"`, the servo loop's case). For
footage whose target moves on its own, `"moving"` drops the surroundings (the predictor alone fills gaps, and a far
jump from where the target's own motion puts it needs a unique match); `"auto"` decides from the first aligned frames
(`hvs-sim track`'s default).
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque

import cv2
import numpy as np

from hvs_sim.tracking.aligner import RECTIFY_DEG, RECTIFY_SCALE, Aligner
from hvs_sim.tracking.base import Estimate, Mode, Tracker
from hvs_sim.tracking.cuts import CUT_MIN_CONTRAST, CUT_THUMB, thumbnail  # noqa: F401 (importable from here)
from hvs_sim.tracking.evidence import appearance, context_agreement, ring_steadiness
from hvs_sim.tracking.hybrid_config import (  # noqa: F401  (HybridConfig and its constants, importable from here)
    APPEARANCE_HISTORY,
    APPEARANCE_RECORD_OCC,
    APPEARANCE_SLACK,
    CONFIDENCE_HALF_LIFE,
    CONTEXT_MARGIN,
    HOMOGRAPHY_LK_EPS,
    HYBRID_LK,
    HYBRID_LK_HOMOGRAPHY,
    HYBRID_MARGIN,
    LOST_NOTES,
    PERSPECTIVE_HISTORY,
    PERSPECTIVE_MAX_OCC,
    PREDICTED_CONFIDENCE,
    PULL_CHECK_OCC,
    PULL_CHECK_PX,
    PULL_FAR_PX,
    PULL_RING_STEADY,
    REACQUIRE_AFTER,
    SURROUNDINGS_GUESSES,
    TARGET_MOTIONS,
    HybridConfig,
    hybrid_deep_config,
)
from hvs_sim.tracking.occlusion import OcclusionReference, aligned_patch
from hvs_sim.tracking.predictors import make_predictor
from hvs_sim.tracking.sources import (
    HybridState,
    KeyframeAnchorSource,
    Kind,
    MotionSource,
    PredictorSource,
    SceneMotionSource,
)
from hvs_sim.tracking.trackability import check_trackable
from hvs_sim.tracking.warp import apply, matrix_to_pose, translate


class HybridTracker(Tracker):
    name = "hybrid"

    def __init__(self, config: HybridConfig | None = None):
        super().__init__()
        config = HybridConfig() if config is None else config
        self.hconfig = config
        self.config = config.deep
        self.aligner = Aligner(config.deep)
        self.warp = config.deep.warp
        predictor = make_predictor(config.predictor, config.history, config.gru_weights)
        self.scene_sources: list[MotionSource] = []  # what the surroundings say: a static target's motion
        self.anchor = None
        if config.background and config.reanchor:
            self.anchor = KeyframeAnchorSource(self.aligner, config.background_config, config.background_gate_px)
            self.scene_sources.append(self.anchor)
        self.scene_motion = None
        if config.background:
            self.scene_motion = SceneMotionSource(self.aligner, config.background_config, config.background_gate_px,
                                                  continues=config.background_gate_continues,
                                                  widen=config.background_gate_sway,
                                                  inertia=config.scene_inertia_frames)
            self.scene_sources.append(self.scene_motion)
        self.predictor_source = PredictorSource(predictor, config.max_predict_frames)
        self.sources: list[MotionSource] = []
        self.state: HybridState | None = None
        self.target_motion: str | None = None  # "static" or "moving"; None while `auto` is still deciding
        # wall ms per stage of the last update (STAGES; the benchmark reads it): prepare (grey, working images), coarse
        # (global match, seeds' OP_t), occlusion, features (VGG), lk, refine (ECC, homography), sources (predict path)
        self.stage_ms: dict[str, float] = {}

    @property
    def working_scale(self) -> float:
        return self.hconfig.deep.scale

    def with_scale(self, scale: float) -> HybridTracker:
        tracker = type(self)(dataclasses.replace(self.hconfig, deep=dataclasses.replace(self.hconfig.deep, scale=scale)))
        tracker.name = self.name
        return tracker

    def _init(self, frame, roi) -> None:
        al = self.aligner
        self._perspective_on = self.hconfig.perspective and self.warp == "similarity"  # a homography's is its own
        work = al.set_template(frame, roi, intensity=self._perspective_on)
        # the similarity's last corrections: where each puts the template's corners, in the template's frame (_reported)
        self._perspectives: deque[np.ndarray] = deque(maxlen=PERSPECTIVE_HISTORY)
        self.template_confidence = check_trackable(al.template, self.config.min_trackability,
                                                   self.config.allow_untrackable, self.name, self.notes)
        self.colour_reference = None  # OP_t in colour (occlusion.py), when configured and the frames have colour
        if self.hconfig.colour_occlusion and frame.ndim == 3:
            self.colour_reference = OcclusionReference(al.template_patch(al.work_colour(frame)), self.config.tau_pix,
                                                       self.config.normalise_exposure)
        self.state = HybridState(center0=self.center0, corners0=self.corners0, A=np.eye(3), keyframe=(work, np.eye(3)),
                                 thumb=thumbnail(work))
        c = self.hconfig
        self.target_motion = None if c.target_motion == "auto" else c.target_motion
        self._evidence, self._evidence_frames, self._aligned_frames = np.zeros(2), 0, 0
        self._appearance_seen: deque[float] = deque(maxlen=APPEARANCE_HISTORY)  # confident alignments' appearance
        self._lost_episodes = 0  # `lost` episodes begun (LOST_NOTES of them are explained in the notes)
        self.sources = ([self.predictor_source] if self.target_motion == "moving" else
                        [*self.scene_sources, self.predictor_source])
        for s in self.sources:
            s.reset(self.state)

    def _seed(self, A: np.ndarray) -> None:
        """The estimate moves to A; the motion sources start again from it (the keyframe stays the template's)."""
        self.state.A = A.copy()
        self._perspectives.clear()  # measured on the target again before it is reported (_reported)
        self.aligner.set_shape(None)
        self.state.scene_held = False  # a pose given from outside, not measured on these frames
        for s in self.sources:
            s.reset(self.state)

    def _occlusion_at(self, frame: np.ndarray, A_seed: np.ndarray, grey_op: float | None) -> float:
        """OP_t at a work warp (the chosen seed, or an alignment): in colour when configured (occlusion.py), else the
        grey value measured there (`grey_op`, None only with colour)."""
        if self.colour_reference is None:
            return grey_op
        al = self.aligner
        near, offset = al.work_colour_near(frame, A_seed)
        patch, inside = aligned_patch(near, translate(A_seed, -offset), al.t_origin, (al.th, al.tw))
        return self.colour_reference(patch, inside)

    def _occlusion_measured(self, frame: np.ndarray, work: np.ndarray, A_work: np.ndarray) -> float:
        """OP_t at a work warp where nothing was measured yet: in grey on `work` unless in colour (_occlusion_at)."""
        grey = None if self.colour_reference is not None else self.aligner.occlusion(work, A_work)
        return self._occlusion_at(frame, A_work, grey)

    def _verified(self, A: np.ndarray, m, work: np.ndarray | None = None) -> bool:
        """Whether an alignment may move the estimate there (HybridConfig.verify_reacquisition). A static target's far
        jump from where the surroundings put it must be unique and seen on several frames, a moving target's from where
        its own motion puts it unique: a look-alike on repetitive texture is no reason to leave the track. Where the
        surroundings' motion in `work` carries the last estimate is no jump (a servo's first steps are followed)."""
        c, st = self.hconfig, self.state
        if not c.verify_reacquisition:
            return True
        if self.target_motion == "static" and st.departs_in_scale(A, c.carried_scale_step, REACQUIRE_AFTER):
            return False  # the surroundings carried the view's scale since the last alignment (carried_scale_step)
        unique = self._unique(A, m, work)
        if self._reacquiring():
            return self._reacquisition_verified(A, m, work, unique)
        if self.target_motion != "static":
            expected = self.predictor_source.predictor.peek()
            miss = np.linalg.norm(matrix_to_pose(A, st.center0)[:2] - expected)
            return miss <= c.reacquire_px + c.background_gate_px * st.predict_run or unique
        offset = matrix_to_pose(A, st.center0)[:2] - matrix_to_pose(st.A, st.center0)[:2]
        drifted = st.drifted_frames(c.lookalike_drift and not unique)  # as in a re-acquisition
        allowed = c.reacquire_px + c.background_gate_px * st.predict_run + c.reacquire_drift_px * drifted
        if np.linalg.norm(offset) <= allowed or self._surroundings_agree(A, work):
            st.jump_seen(None, 0.0)
            return True
        if not unique:
            st.jump_seen(None, 0.0)
            return False
        seen = st.jump_seen(offset, c.background_gate_px)
        if self._context_overrules(work, A):
            return True
        held = st.scene_held and st.drift_run <= SURROUNDINGS_GUESSES
        if c.surroundings_veto_frames and held and seen < c.surroundings_veto_frames:
            return False  # the surroundings, measured since the alignment, put the target elsewhere
        return seen >= c.reacquire_frames

    def _reacquiring(self) -> bool:
        """Whether an alignment now is a re-acquisition (after `lost`, a cut or REACQUIRE_AFTER unaligned frames)."""
        st = self.state
        return st.is_lost or st.after_cut or st.since_aligned >= REACQUIRE_AFTER

    def _unique(self, A: np.ndarray, m, work: np.ndarray | None) -> bool:
        """No look-alike elsewhere: the match's peak stands out from the rest of the frame (reacquire_margin). The
        search used the estimate's θ and s; where the alignment found the target turned or scaled from them (a
        camera that rolled or came closer while the target was not aligned), that template scores the true target
        little above, or under, the look-alikes around it (0.80 against 0.84 for a view rolled 12° while hidden), so
        the search is made again in the aligned shape, and its peak must be where the target was aligned."""
        c, st, al = self.hconfig, self.state, self.aligner
        if m.score - m.second >= c.reacquire_margin:
            return True
        if work is None:
            return False
        _, _, theta, scale = matrix_to_pose(A, st.center0)
        _, _, theta_est, scale_est = matrix_to_pose(st.A, st.center0)
        if abs(theta - theta_est) <= np.radians(RECTIFY_DEG) and abs(scale / scale_est - 1) <= RECTIFY_SCALE:
            return False  # searched in this shape already
        # the template in A's shape (Aligner.rectified_template's cached one is left as it is)
        again = al.matcher.match(work, al.shaped_template(theta, scale))
        centre = apply(al.to_work(A), al.c_work[None])[0]
        return (again.score - again.second >= c.reacquire_margin
                and bool(np.linalg.norm(again.center - centre) <= c.reacquire_px * self.config.scale))

    def _looks_like_target(self, work: np.ndarray, A: np.ndarray) -> bool:
        """Whether the patch at A (full res) shows the target as this track's confident alignments showed it
        (evidence.appearance within APPEARANCE_SLACK of their median, and at least the match threshold)."""
        seen = float(np.median(self._appearance_seen)) if self._appearance_seen else 1.0
        bar = max(self.config.match_threshold, seen - APPEARANCE_SLACK)
        return appearance(self.aligner, work, self.aligner.to_work(A)) >= bar

    def _reacquisition_verified(self, A: np.ndarray, m, work: np.ndarray | None, unique: bool) -> bool:
        """A re-acquisition (REACQUIRE_AFTER): the target found again after a loss, a cut or a long gap. Every
        check must agree: the aligned patch looks like the target (_looks_like_target); and either it lies where
        the surroundings, measured on these frames, put the target (a static target, not lost), or the match is
        unique (no look-alike within the frame, nor along a weakly textured target's own direction) and seen at one
        place on `reacquire_frames` consecutive frames. Distance from a guess is no evidence: after many
        predicted frames the predictor's bound would take in any look-alike nearby."""
        c, st = self.hconfig, self.state
        if work is None or not self._looks_like_target(work, A):
            st.jump_seen(None, 0.0)
            return False
        offset = matrix_to_pose(A, st.center0)[:2] - matrix_to_pose(st.A, st.center0)[:2]
        measured = (self.target_motion == "static" and not (st.is_lost or st.after_cut) and st.scene_held
                    and st.drift_run <= SURROUNDINGS_GUESSES)
        drifted = st.drifted_frames(c.lookalike_drift and not unique)  # the estimate's drift (reacquire_drift_px)
        if measured and (np.linalg.norm(offset) <= c.reacquire_px + c.reacquire_drift_px * drifted
                         or self._surroundings_agree(A, work)):
            st.jump_seen(None, 0.0)
            return True
        if not unique:
            st.jump_seen(None, 0.0)
            return False
        # a static target's estimate follows the view, so the same place keeps its offset; a moving one's may not
        tolerance = c.background_gate_px if self.target_motion == "static" else c.reacquire_px
        seen = st.jump_seen(offset, tolerance)
        if self._context_overrules(work, A):
            return True
        if measured and c.surroundings_veto_frames and seen < c.surroundings_veto_frames:
            return False  # the surroundings, measured since the alignment, put the target elsewhere
        return seen >= c.reacquire_frames

    def _context_overrules(self, work: np.ndarray | None, A: np.ndarray) -> bool:
        """Whether the target's own surroundings, as the template's view showed them, put it at the unique far match A
        and not at the estimate (HybridConfig.context_agree): the estimate went wrong, not the match, which is taken
        then without the surroundings' veto or waiting `reacquire_frames` (at 10 fps a guessed estimate moved 10-15 px
        a frame from the visible target, so its offset never held for three frames)."""
        c, al = self.hconfig, self.aligner
        if not c.context_check or work is None:
            return False
        there, here = (context_agreement(al, work, al.to_work(B)) for B in (A, self.state.A))
        return there is not None and there >= c.context_agree and (here is None or there - here >= CONTEXT_MARGIN)

    def _pulled(self, frame: np.ndarray, A: np.ndarray, occ: float, work: np.ndarray) -> bool:
        """Whether an occluder pulled this alignment (HybridConfig.pull_check): a static target aligned on the frame
        before, partly covered now (OP_t over PULL_CHECK_OCC; or clear where the ring around it changed, `pull_check_
        clear`, the scene then measured in a quick hop), over PULL_CHECK_PX from where the surroundings' motion since
        then puts it, and its visible pixels fitting there no better than at their pose (Aligner.shows_clearly).
        Robust LK still moved 0.8-1.7 px a frame towards a coat's edge over 2-14 % of the target, and the chain carried
        that through the coat's 3.5 s stay (photos' dev split, `long` ascent of seed 2027: 2.7 px at OP_t 0.18). The
        image decides as either can be wrong: the surroundings' hop can be the coat's (13 px); OP_t could not tell a
        hand's 3.5 px pull on a smooth photo, nor a person wearing the target's picture (`camo`). With
        `pull_check_carried` also after frames the surroundings carried a covered target, and a far miss must be one
        the template can tell (HybridConfig)."""
        covered, c, al, st = occ > PULL_CHECK_OCC, self.hconfig, self.aligner, self.state
        # aligned on the frame before, or (`pull_check_carried`) a covered target the surroundings alone carried since:
        # their pose is then chained over several hops, and only a miss over PULL_FAR_PX is told from their own error
        if not (st.since_aligned == 0 or (c.pull_check_carried and covered and st.measured_only)):
            return False
        if not (c.pull_check and self.target_motion == "static" and (covered or c.pull_check_clear)
                and self.scene_motion is not None):
            return False
        if not covered and ring_steadiness(al, *self.scene_motion.key, work, al.to_work(A)) >= PULL_RING_STEADY:
            return False  # the surroundings moved with the alignment, and nothing came into them: no pull to look for
        found = self._surroundings_miss(A, work, quick=not covered)
        if found is None or found[1] <= (PULL_CHECK_PX if st.since_aligned == 0 else PULL_FAR_PX):
            return False
        B = al.to_work(found[0])
        visible = 1.0 - max(occ, self._occlusion_measured(frame, work, B))
        # far from their pose, the image speaks for the alignment only where the template tells the two poses apart
        far = c.pull_check_carried and found[1] > PULL_FAR_PX
        return not al.shows_clearly(work, al.to_work(A), B, visible, c.pull_evidence, discernible=far)

    def _surroundings_miss(self, A: np.ndarray, work: np.ndarray, quick: bool = False
                           ) -> tuple[np.ndarray, float] | None:
        """The pose the surroundings' motion since the last measured frame gives (SceneMotionSource.measure peeking, or
        quick_peek), and how far A's centre is from its centre; None where they cannot be measured."""
        B = self.scene_motion.quick_peek(work) if quick else self.scene_motion.measure(work, self.state, peek=True)
        if B is None:
            return None
        center0 = self.state.center0
        return B, float(np.linalg.norm(matrix_to_pose(A, center0)[:2] - matrix_to_pose(B, center0)[:2]))

    def _surroundings_agree(self, A: np.ndarray, work: np.ndarray | None) -> bool:
        """Whether the surroundings' motion since the last measured frame puts the target within reacquire_px of A
        (SceneMotionSource.measure, peeking; False without the surroundings, or where they cannot be measured)."""
        st = self.state
        if work is None or self.scene_motion is None or not (st.scene_held and st.drift_run <= SURROUNDINGS_GUESSES):
            return False  # the veto's condition: the estimate is the surroundings' (a seed's or a long guess's is not)
        found = self._surroundings_miss(A, work)
        return found is not None and found[1] <= self.hconfig.reacquire_px

    def _judge_motion(self, work: np.ndarray, A: np.ndarray) -> None:
        """`auto`: add this aligned frame's evidence (where the aligned target is, against where the surroundings'
        motion since the last alignment puts it), and decide once there is enough (HybridConfig.target_motion)."""
        c, st = self.hconfig, self.state
        self._aligned_frames += 1
        A_scene = self.scene_motion.measure(work, st) if self.scene_motion is not None else None
        if A_scene is not None:
            self._evidence += matrix_to_pose(A, st.center0)[:2] - matrix_to_pose(A_scene, st.center0)[:2]
            self._evidence_frames += 1
        if self._evidence_frames < c.auto_frames and self._aligned_frames < 3 * c.auto_frames:
            return
        offset = float(np.linalg.norm(self._evidence))
        self.target_motion = "moving" if offset > c.moving_px else "static"
        if self.target_motion == "moving":
            self.sources = [self.predictor_source]
        seen = (f"the aligned target ended {offset:.1f} px from where its surroundings' motion put it over "
                f"{self._evidence_frames} frames" if self._evidence_frames else "the surroundings could not be measured")
        self.notes.append(f"target motion: auto chose {self.target_motion} at frame {st.frame_index} ({seen}; "
                          f"over {c.moving_px:g} px means moving)")

    def _unaligned_confidence(self, kind: Kind) -> float:
        """Confidence of a pose not aligned on this frame: it halves every CONFIDENCE_HALF_LIFE frames since the last
        alignment, and a predictor's guess counts PREDICTED_CONFIDENCE of a measurement (0 when lost: base class)."""
        decay = 0.5 ** (self.state.since_aligned / CONFIDENCE_HALF_LIFE)
        return self.template_confidence * decay * (PREDICTED_CONFIDENCE if kind == Kind.PREDICTED else 1.0)

    def _update(self, frame) -> Estimate:
        return self._reported(self._estimate(frame))

    def _reported(self, est: Estimate) -> Estimate:
        """The estimate as reported (HybridConfig.perspective). On an aligned frame with the target in full view
        (PERSPECTIVE_MAX_OCC), the similarity's correction A⁻¹·H to the homography Aligner.perspective measures there
        joins the last PERSPECTIVE_HISTORY ones; the pose is reported with their median (of where each puts the
        template's corners): a view's tilt changes slowly, while an occluder OP_t cannot see pulls one frame's
        refinement (photos' dev split, `camo`). `lost` and a seed empty the history; with lk_perspective the median
        then mixes corrections measured on the similarity alone and on S (Aligner.set_shape) for a few frames."""
        if not self._perspective_on:
            return est
        if est.mode == Mode.LOST:
            self._perspectives.clear()
            self.aligner.set_shape(None)
            return est
        if est.mode == Mode.ALIGN and est.occlusion <= PERSPECTIVE_MAX_OCC:
            H = self.aligner.perspective(self.aligner.to_work(est.A))
            if H is not None:  # where the correction puts the template's corners (in the template's frame)
                self._perspectives.append(apply(np.linalg.solve(est.A, self.aligner.to_full(H)), self.corners0))
        if not self._perspectives:
            return est
        corners = np.median(np.stack(self._perspectives), axis=0)
        C = cv2.getPerspectiveTransform(self.corners0.astype(np.float32), corners.astype(np.float32))
        if self.hconfig.lk_perspective:
            self.aligner.set_shape(C)
        return dataclasses.replace(est, A=est.A @ C)

    def _estimate(self, frame) -> Estimate:
        """The frame's estimate of the paper's warp (module docstring)."""
        al, st = self.aligner, self.state
        al.stage_ms = self.stage_ms = {}
        st.frame_index += 1
        t0 = time.perf_counter()
        work = al.work_image(frame)
        cut = st.saw(thumbnail(work)) < self.hconfig.cut_ncc  # nothing of the last frame is in this one
        if cut and self.target_motion is None:  # `auto`'s evidence compares with the surroundings, which a cut ends
            self._evidence, self._evidence_frames = np.zeros(2), 0
        t1 = time.perf_counter()
        m, A_seed, occ, is_current = al.coarse(work, st.A)
        t2 = time.perf_counter()
        occ = self._occlusion_at(frame, A_seed, occ)
        t3 = time.perf_counter()
        self.stage_ms.update(prepare=1e3 * (t1 - t0), coarse=1e3 * (t2 - t1), occlusion=1e3 * (t3 - t2))
        if m.score <= 0:  # blank or uniform frame
            occ = 1.0
        if is_current:  # OP_t at the estimate: how much of the target is covered (background.COVERED_OP, CLEAR_OP),
            st.hidden_share = occ  # for the checks of an alignment too
        gate = self.hconfig.occlusion_gate
        confident = m.score > 0 and (m.score >= self.config.match_threshold or (self.hconfig.continuity and is_current))
        if confident and (occ < gate or self.hconfig.gate_after_alignment):
            # θ and s may continue the estimate's, measured drift_run + 1 frames ago (guesses carry neither); in a
            # re-acquisition (_verified checks it) also the last alignment's, since_aligned + 1 frames ago: surroundings
            # skewed by an occluder must not leave the target refused once it shows (a fresh `pause`: the estimate
            # scaled 12 % with the arm held). Not sooner: at dev `pause` seed 365 a person was aligned 10 frames in
            reacquiring = self._reacquiring() and st.aligned_A is not None
            last = (al.to_work(st.aligned_A), st.since_aligned + 1) if reacquiring else None
            A_new = al.align(work, A_seed, al.to_work(st.A), frames=st.drift_run + 1, aligned=last).A_work
            occ_aligned = occ
            if A_new is not None and occ >= gate:  # gated again where the target was aligned (gate_after_alignment)
                occ_aligned = self._occlusion_measured(frame, work, A_new)
                if occ_aligned >= gate:
                    A_new = None
            if A_new is not None and self._pulled(frame, al.to_full(A_new), occ_aligned, work):
                A_new = None
            if A_new is not None and self._verified(al.to_full(A_new), m, work):
                if occ_aligned <= APPEARANCE_RECORD_OCC:  # what the target looks like when surely found
                    self._appearance_seen.append(appearance(al, work, A_new))
                if self.target_motion is None:
                    self._judge_motion(work, al.to_full(A_new))
                st.aligned(work, al.to_full(A_new), self.sources)
                return Estimate(st.A, Mode.ALIGN, occ_aligned, m.score)
            if occ_aligned >= gate:  # not gated in (where _verified ran, it keeps its own count)
                st.jump_seen(None, 0.0)
        else:
            st.jump_seen(None, 0.0)
        t4 = time.perf_counter()
        if not is_current:  # not measured at the estimate yet
            st.hidden_share = self._occlusion_measured(frame, work, al.to_work(st.A))
        est = self._predict(work, occ, m, cut)
        self.stage_ms["sources"] = 1e3 * (time.perf_counter() - t4)
        return est

    def _lost(self, work: np.ndarray, reason: str, cut: bool) -> None:
        """The `lost` transition; the first frame of a `lost` episode says why in the notes (LOST_NOTES of them)."""
        st = self.state
        if not st.is_lost:
            self._lost_episodes += 1
            if self._lost_episodes <= LOST_NOTES:
                self.notes.append(f"lost at frame {st.frame_index}: {reason}; the target's appearance last matched "
                                  f"its template {st.since_aligned} frames before")
            elif self._lost_episodes == LOST_NOTES + 1:
                self.notes.append(f"lost again from frame {st.frame_index} (later episodes are not listed)")
        st.lost(work, self.sources, cut=cut)

    def _predict(self, work: np.ndarray, occ: float, m, cut: bool) -> Estimate:
        """The first motion source with a proposal moves the estimate (module docstring); after a scene cut, or too
        long without an alignment, the estimate is lost until the target is aligned again."""
        st = self.state
        if st.after_cut and not cut and self.anchor in self.sources:  # the view may have come back (a full-view
            proposal = self.anchor.propose(work, st)  # occluder, not a cut): only the aligned keyframes can say so
            if proposal is not None:
                st.measured(work, proposal, self.sources)
                return Estimate(st.A, proposal.mode, occ, m.score, self._unaligned_confidence(proposal.kind))
        c = self.hconfig
        reason = None
        if cut or st.after_cut:
            reason = "a scene cut (the frame shares nothing with the one before)"
        elif st.since_aligned >= c.max_unaligned_frames:
            reason = f"not aligned for {st.since_aligned} frames, whatever the surroundings say"
        elif self.target_motion is None and st.since_aligned >= c.max_predict_frames:
            # `auto` has not yet seen the target stay put in its surroundings: their motion is no more its motion
            # than a guess, and a target that moves or changes shape is not where they put it
            reason = (f"not aligned for {st.since_aligned} frames while its motion was still undecided: the "
                      "surroundings cannot say where it is")
        if reason is not None:
            self._lost(work, reason, cut)
            return Estimate(st.A, Mode.LOST, occ, m.score, 0.0)
        for source in self.sources:
            proposal = source.propose(work, st)
            if proposal is None:
                continue
            if proposal.kind == Kind.PREDICTED:
                if proposal.mode == Mode.LOST:
                    self._lost(work, f"nothing measured its position for {st.predict_run} frames", False)
                else:
                    st.predicted(work, proposal.A, self.sources)
            else:
                st.measured(work, proposal, self.sources)
            return Estimate(st.A, proposal.mode, occ, m.score, self._unaligned_confidence(proposal.kind))
        raise AssertionError("the predictor source always proposes")  # pragma: no cover
