"""The paper's hybrid tracker: global match → occlusion gate → deep LK + residual, or motion prediction.

Per frame: NCC over the whole frame gives a coarse centre and a score; OP_t is measured on the
patch at that centre and on the patch at the current estimate, and the better of the two is kept
(see DeepLKTracker.coarse). If OP_t < gate (40 %) and the match score ≥ 0.6 (or, with
`continuity`, the seed is the current estimate) the frame is aligned (feature LK, then
the residual regressor) and its translation joins the predictor's history; otherwise the predictor
(GRU by default) extrapolates the translation, holding θ and s. With `gate_after_alignment` (a change
to the paper, on by default) a confident seed whose OP_t fails the gate is aligned anyway, and OP_t
at the aligned pose decides: a seed a few pixels off reads its misalignment as occlusion. Re-acquisition is automatic: the
global match runs every frame, so the first frame that passes the gate is aligned again.

Two changes to the paper in the predict path, both on by default and both measured (README, tracking benchmark;
`background=False, colour_occlusion=False` is the paper's hybrid as published):
- Predicting from the scene around the target (`background`, background.py): while the target is
  hidden the wall around it usually is not, so the predict path first moves the target's last
  aligned pose by the similarity motion of the surroundings since that frame. That measures the
  camera's motion, where the GRU can only extrapolate it (hand-held tremor is not predictable over
  a 1.8 s occlusion). The GRU (or the configured predictor) takes over on frames where the
  surroundings give no trustworthy motion (a person filling the whole view), continuing from the
  last background-based positions. After such predictor-only frames the chain would carry the
  predictor's error to the end of the occlusion, so as soon as the wall shows again the frame is
  measured against earlier aligned keyframes instead (`reanchor`, background.KeyframeAnchor).
- OP_t over colour channels (`colour_occlusion`, occlusion.py): grey OP_t reported a flag half
  covered by a brown sleeve as clear, so LK aligned on the sleeve.

Built from parts (ViSP-style composition rather than inheritance): an `Aligner` (global match, feature
LK, residual), the OP_t gate, and motion sources tried in order on frames that are not aligned
(sources.py: keyframe anchor → scene motion → predictor). `HybridState` holds everything that
changes from frame to frame, and its four transitions — aligned, measured, predicted, lost — are
the only way it changes.

The extrapolating predictor is bounded: after `max_predict_frames` consecutive frames with neither
an alignment nor a background measurement (default 45, 1.5 s at 30 Hz) the mode becomes "lost" and
the estimate stops moving until re-acquisition. A scene cut (`cut_ncc`) and `max_unaligned_frames`
without an alignment also end in "lost", whatever the surroundings say.

All of the above takes the target to be fixed in the scene (`target_motion="static"`, the servo loop's case). For
footage whose target moves on its own, `"moving"` drops the surroundings (the predictor alone fills gaps, and a far
jump from where the target's own motion puts it needs a unique match); `"auto"` decides from the first aligned frames
(`hvs-sim track`'s default).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.aligner import Aligner, DeepLKConfig
from hvs_sim.tracking.background import BackgroundConfig
from hvs_sim.tracking.base import Estimate, Mode, Tracker
from hvs_sim.tracking.feature_lk import LKConfig
from hvs_sim.tracking.occlusion import OcclusionReference, aligned_patch
from hvs_sim.tracking.predictors import PREDICTORS, make_predictor
from hvs_sim.tracking.sources import (
    HybridState,
    KeyframeAnchorSource,
    Kind,
    MotionSource,
    PredictorSource,
    SceneMotionSource,
)
from hvs_sim.tracking.trackability import check_trackable
from hvs_sim.tracking.warp import matrix_to_pose, translate
from hvs_sim.validate import check_flags

# The hybrid's feature LK (README, tracker speed). The global match seeds it within about a work pixel on
# every frame it aligns, so it starts at pool1 (stride 2) without pool2's wider basin, which cost the
# conv2 layers and a third of the LK; and it runs in the 8-channel subspace of the template's principal
# feature gradients (LKConfig.channels). A 5 px margin (8 for deep_lk) still leaves 2 px beyond the
# LK's border for the alignment to move; the global searches run only when a search near the estimate does
# not confirm it (Aligner.coarse). It stops a level at an update of 1e-2 × stride work px (3e-2 before the
# last level; deep_lk: 2e-3 and 1e-2): on the speed benchmark's frames the aligned corners moved by 0.003 px
# (median; at most 0.009) and an alignment took 6.8 iterations instead of 9.2 (README, hybrid speed). The
# residual variants keep deep_lk's alignment: the regressor reads pool2.
HYBRID_LK = LKConfig(levels=("pool1", "conv1_2"), iterations=(15, 8), channels=8, eps=1e-2, coarse_eps=3e-2)
# With the homography, the intensity refinement (Aligner.refine_intensity, intensity_ic.py) takes the LK's answer to
# the full-resolution optimum, so conv1_2 only has to bring it within that refinement's reach: 3 iterations there
# instead of up to 8 (5.4 on average). On the speed benchmark's frames that took ~0.5 ms off the homography
# hybrid's median, and the corners on warped photos and tilted hand-held sequences stayed where 8 left them (within
# 0.003 px in the median; README, homography). pool1 alone was faster again but ended 3–11 px off on a tenth of the
# warped photos, from the identity. For the same reason each level stops sooner than the similarity's: pool1 lands
# 0.3–0.6 work px from conv1_2's optimum (its first update there), so it stops at 0.2 px (0.1 × its stride), and
# conv1_2's updates run ~0.5, 0.07, 0.015 px, so it stops at 0.1 px and the refinement takes the rest in a cheaper
# step. On bench_homography's tilted hand-held sequences that took the homography's cost from 1.44 to 1.24–1.31× the
# similarity's (with the cheaper per-frame steps beside it), the errors there and on the warped photos within
# 0.01 px (docs/tuning.md).
HOMOGRAPHY_LK_EPS = 0.1
HYBRID_LK_HOMOGRAPHY = replace(HYBRID_LK, iterations=(15, 3), eps=HOMOGRAPHY_LK_EPS, coarse_eps=HOMOGRAPHY_LK_EPS)
HYBRID_MARGIN = 5


def _thumb(work: np.ndarray) -> np.ndarray | None:
    """A small zero-mean, unit-norm copy of the working image: two frames of one shot correlate on it, a cut does not.
    None for a frame without content to compare (a body or a hand filling the view, the lens covered): that is an
    occlusion, not a cut."""
    t = cv2.resize(np.asarray(work, np.float32), CUT_THUMB, interpolation=cv2.INTER_AREA).ravel()
    t = t - t.mean()
    norm = float(np.linalg.norm(t))
    return None if norm < CUT_MIN_CONTRAST * np.sqrt(t.size) else t / norm


def hybrid_deep_config(residual: bool = False, warp: str = "similarity") -> DeepLKConfig:
    """The hybrid's default alignment settings: the fast LK above (for `warp`), or, with the residual regressor,
    deep_lk's (pool2 → pool1 → conv1_2 on all channels)."""
    if residual:
        return DeepLKConfig()
    lk = HYBRID_LK_HOMOGRAPHY if warp == "homography" else HYBRID_LK
    return DeepLKConfig(lk=lk, margin=HYBRID_MARGIN, always_search_as_taken=False, search_near_first=True,
                        intensity_smooth="frame")


TARGET_MOTIONS = ("static", "moving", "auto")  # HybridConfig.target_motion
CUT_THUMB = (32, 24)  # the thumbnail two frames are compared on for a scene cut (w, h)
CUT_MIN_CONTRAST = 2.0 / 255  # a thumbnail with less RMS contrast (intensity in [0, 1]) has nothing to compare

# predictor frames since the last alignment or re-anchoring after which the estimate is no longer the surroundings'
# (HybridConfig.surroundings_veto_frames): half a second of guesses. A shirt printed with the scene's texture left the
# chain unmeasured for 6 frames before its far match came (natural benchmark, `lookalike`); a jump within the
# predictor's possible drift is accepted anyway (HybridConfig.reacquire_px, background_gate_px)
SURROUNDINGS_GUESSES = 15
CONFIDENCE_HALF_LIFE = 30  # frames (1 s at 30 Hz) since the last alignment over which an unaligned pose's confidence halves
PREDICTED_CONFIDENCE = 0.5  # a predictor's guess, relative to a measurement of the scene's motion


@dataclass(frozen=True)
class HybridConfig:
    # the residual regressor is off: on held-out data it did not earn its place (README, learned modules)
    deep: DeepLKConfig = field(default_factory=hybrid_deep_config)
    occlusion_gate: float = 0.4
    predictor: str = "gru"
    history: int = 10
    max_predict_frames: int = 45
    gru_weights: str | None = None
    # True: a seed that continues the current track and passes the OP_t gate needs no NCC score
    # (partial occlusion drags the score below 0.6). Measured: more frames aligned under partial
    # occlusion but drift onto the occluder in others (README, tracking benchmark), so the paper's
    # rule (score ≥ 0.6 always) stays the default.
    continuity: bool = False
    colour_occlusion: bool = True  # OP_t over colour channels (occlusion.py); False: grey, as the paper
    # a confident seed whose OP_t fails the gate is aligned anyway, and the frame counts as aligned when OP_t at the
    # aligned pose passes it (a change to the paper, which gates on the seed alone). OP_t at a seed that is off by a
    # few pixels counts the misalignment as occlusion: a sharp photo under a 4 px perspective warp read 0.41 at the
    # seed and 0.02 once aligned (README, homography). An occluder that pulls LK away leaves OP_t high where LK ended.
    gate_after_alignment: bool = True
    background: bool = True  # predict from the surroundings' similarity motion first (module docstring)
    # most a background-measured position may differ from the last estimate (px, per frame since
    # the last measurement); 8 px let a wrong 17 px jump through on a validation sequence (README)
    background_gate_px: float = 4.0
    background_config: BackgroundConfig = field(default_factory=BackgroundConfig)
    reanchor: bool = True  # after predictor-only frames, measure against aligned keyframes (KeyframeAnchor)
    # verified re-acquisition (a change to the paper): an alignment further than `reacquire_px` (plus
    # `background_gate_px` per unmeasured frame, plus `reacquire_drift_px` per frame since the last
    # alignment: the scene-motion chain drifts as it grows) from where the motion sources put the target is
    # accepted only when the global match is unique (best NCC − second-best peak ≥ `reacquire_margin`)
    # and the same jump is seen on `reacquire_frames` consecutive frames. On self-similar texture (fur,
    # gravel) the NCC peak can sit on a look-alike patch while the target is hidden.
    verify_reacquisition: bool = True
    reacquire_px: float = 8.0
    # a 60-frame chain through a person filling the view ended 10.8 px off on a validation sequence
    # (pause seed 110), and a stricter bound kept the visible target from being re-acquired
    reacquire_drift_px: float = 0.5
    reacquire_margin: float = 0.1
    reacquire_frames: int = 3
    # a static target's far jump that the surroundings contradict: while the frames since the last alignment were
    # measured on the surroundings (at most SURROUNDINGS_GUESSES predictor guesses, no seed), they say where the
    # target is, and a unique match far from there is a look-alike (clothing printed with the scene's own texture,
    # paused over the target), refused until seen on this many consecutive frames (3 s at 30 Hz: a chain that went
    # wrong is not held forever). 0: off (docs/results.md, harder occluders)
    surroundings_veto_frames: int = 90
    # what the target does: "static" (fixed in the scene, the servo case: the surroundings' motion is its motion, and
    # a far jump must be verified), "moving" (it moves on its own, as footage often shows: a confident match is never
    # vetoed by the surroundings, and the predictor extrapolates the target's own motion), or "auto": "moving" for
    # the first `auto_frames` aligned frames, then whichever the net offset of the aligned target from where the
    # surroundings' motion put it says (over `moving_px`: moving). The choice is in the tracker's `notes`.
    target_motion: str = "static"
    auto_frames: int = 15
    moving_px: float = 6.0
    # a scene cut: the frame's thumbnail correlates below `cut_ncc` with the previous one and the target is not found;
    # the estimate is then lost (the surroundings' chain cannot cross a cut) until the target is aligned again
    cut_ncc: float = 0.3
    # a long run without an alignment ends in `lost`, whatever the surroundings say (10 s at 30 Hz)
    max_unaligned_frames: int = 300

    @classmethod
    def for_warp(cls, label: str = "hybrid", /, **settings) -> HybridConfig:
        """The hybrid's defaults for its warp model (`warp`, `residual` among `settings`), with `settings`
        (HybridConfig fields, and DeepLKConfig fields for the alignment) changed: the one place they are built and
        checked. `make_tracker("hybrid", ...)` and the registry's variants come here, so every way of asking for a
        hybrid gives the same tracker; `HybridConfig(deep=...)` takes an alignment config whole, every field as
        given. `label` (positional) names the tracker in an error, e.g. a registry variant."""
        from dataclasses import fields

        hybrid_keys = {f.name for f in fields(cls)} - {"deep"}
        deep_keys = {f.name for f in fields(DeepLKConfig)}
        unknown = set(settings) - hybrid_keys - deep_keys
        if unknown:
            raise ConfigError(f"{label}: unknown setting(s) {', '.join(sorted(unknown))}; accepted: "
                              f"{', '.join(sorted(hybrid_keys | deep_keys))}")
        base = hybrid_deep_config(residual=bool(settings.get("residual", False)),
                                  warp=settings.get("warp", "similarity"))
        deep = replace(base, **{k: v for k, v in settings.items() if k in deep_keys})
        return cls(deep=deep, **{k: v for k, v in settings.items() if k in hybrid_keys})

    def __post_init__(self):
        check_flags(self, ("continuity", "colour_occlusion", "gate_after_alignment", "background", "reanchor",
                           "verify_reacquisition"))
        if not 0 < self.occlusion_gate <= 1:
            raise ConfigError(f"occlusion_gate must be in (0, 1], got {self.occlusion_gate}")
        if self.predictor not in PREDICTORS:
            raise ConfigError(f"unknown predictor {self.predictor!r}; accepted: {', '.join(PREDICTORS)}")
        if not self.background_gate_px > 0:
            raise ConfigError(f"background_gate_px must be > 0, got {self.background_gate_px}")
        if not isinstance(self.max_predict_frames, int) or self.max_predict_frames < 1:
            raise ConfigError(f"max_predict_frames must be an int >= 1, got {self.max_predict_frames!r}")
        if not (self.reacquire_px > 0 and self.reacquire_drift_px >= 0 and 0 <= self.reacquire_margin < 1):
            raise ConfigError(f"need reacquire_px > 0, reacquire_drift_px >= 0 and reacquire_margin in [0, 1), got "
                              f"{self.reacquire_px}, {self.reacquire_drift_px}, {self.reacquire_margin}")
        if not isinstance(self.reacquire_frames, int) or self.reacquire_frames < 1:
            raise ConfigError(f"reacquire_frames must be an int >= 1, got {self.reacquire_frames!r}")
        v = self.surroundings_veto_frames
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ConfigError(f"surroundings_veto_frames must be an int >= 0 (0: off), got {v!r}")
        if self.target_motion not in TARGET_MOTIONS:
            raise ConfigError(f"target_motion must be one of {', '.join(TARGET_MOTIONS)}, got {self.target_motion!r}")
        for name in ("auto_frames", "max_unaligned_frames"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f"{name} must be an int >= 1, got {value!r}")
        if not (self.moving_px > 0 and -1 <= self.cut_ncc < 1):
            raise ConfigError(f"need moving_px > 0 and cut_ncc in [-1, 1), got {self.moving_px}, {self.cut_ncc}")


class HybridTracker(Tracker):
    name = "hybrid"

    def __init__(self, config: HybridConfig = HybridConfig()):
        super().__init__()
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
            self.scene_motion = SceneMotionSource(self.aligner, config.background_config, config.background_gate_px)
            self.scene_sources.append(self.scene_motion)
        self.predictor_source = PredictorSource(predictor, config.max_predict_frames)
        self.sources: list[MotionSource] = []
        self.state: HybridState | None = None
        self.target_motion: str | None = None  # "static" or "moving"; None while `auto` is still deciding
        # wall ms per stage of the last update (STAGES; the benchmark reads it): "prepare" (grey and
        # working images), "coarse" (global match and OP_t of the seeds), "occlusion" (colour OP_t),
        # "features" (VGG), "lk", "refine" (ECC, homography), "sources" (the predict path)
        self.stage_ms: dict[str, float] = {}

    def _init(self, frame, roi) -> None:
        al = self.aligner
        work = al.set_template(frame, roi)
        self.template_confidence = check_trackable(al.template, self.config.min_trackability,
                                                   self.config.allow_untrackable, self.name, self.notes)
        self.colour_reference = None  # OP_t in colour (occlusion.py), when configured and the frames have colour
        if self.hconfig.colour_occlusion and frame.ndim == 3:
            self.colour_reference = OcclusionReference(al.template_patch(al.work_colour(frame)), self.config.tau_pix,
                                                       self.config.normalise_exposure)
        self.state = HybridState(center0=self.center0, corners0=self.corners0, A=np.eye(3), keyframe=(work, np.eye(3)),
                                 thumb=_thumb(work))
        c = self.hconfig
        self.target_motion = None if c.target_motion == "auto" else c.target_motion
        self._evidence, self._evidence_frames, self._aligned_frames = np.zeros(2), 0, 0
        self.sources = ([self.predictor_source] if self.target_motion == "moving" else
                        [*self.scene_sources, self.predictor_source])
        for s in self.sources:
            s.reset(self.state)

    def _seed(self, A: np.ndarray) -> None:
        """The estimate moves to A; the motion sources start again from it (the keyframe stays the template's
        image, where the identity holds)."""
        self.state.A = A.copy()
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

    def _verified(self, A: np.ndarray, m, work: np.ndarray | None = None) -> bool:
        """Whether an alignment may move the estimate there (HybridConfig.verify_reacquisition). A static target's
        far jump from where the surroundings put it must be unique and seen on several frames; a moving target's
        far jump from where its own motion puts it (the predictor) must be unique: a look-alike on repetitive
        texture is no reason to leave the track. A static target's alignment far from the last estimate that the
        surroundings' own motion in `work` carries it to is no jump: a camera that moves faster than reacquire_px a
        frame (a servo's first steps: 10 px a frame) is followed, not refused until it is lost."""
        c, st = self.hconfig, self.state
        if not c.verify_reacquisition:
            return True
        unique = m.score - m.second >= c.reacquire_margin  # no look-alike elsewhere: the peak stands out
        if self.target_motion != "static":
            expected = self.predictor_source.predictor.peek()
            miss = np.linalg.norm(matrix_to_pose(A, st.center0)[:2] - expected)
            return miss <= c.reacquire_px + c.background_gate_px * st.predict_run or unique
        offset = matrix_to_pose(A, st.center0)[:2] - matrix_to_pose(st.A, st.center0)[:2]
        allowed = c.reacquire_px + c.background_gate_px * st.predict_run + c.reacquire_drift_px * st.since_aligned
        if np.linalg.norm(offset) <= allowed or self._surroundings_agree(A, work):
            st.jump_seen(None, 0.0)
            return True
        if not unique:
            st.jump_seen(None, 0.0)
            return False
        seen = st.jump_seen(offset, c.background_gate_px)
        held = st.scene_held and st.drift_run <= SURROUNDINGS_GUESSES
        if c.surroundings_veto_frames and held and seen < c.surroundings_veto_frames:
            return False  # the surroundings, measured since the alignment, put the target elsewhere
        return seen >= c.reacquire_frames

    def _surroundings_agree(self, A: np.ndarray, work: np.ndarray | None) -> bool:
        """Whether the surroundings' motion since the last measured frame puts the target within reacquire_px of A
        (SceneMotionSource.measure, peeking; False without the surroundings, or where they cannot be measured)."""
        st = self.state
        if work is None or self.scene_motion is None or not (st.scene_held and st.drift_run <= SURROUNDINGS_GUESSES):
            return False  # the veto's condition: the estimate is the surroundings' (a seed's or a long guess's is not)
        B = self.scene_motion.measure(work, st, peek=True)
        center0 = st.center0
        return B is not None and bool(np.linalg.norm(matrix_to_pose(A, center0)[:2] - matrix_to_pose(B, center0)[:2])
                                      <= self.hconfig.reacquire_px)

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
        """Confidence of a pose not aligned on this frame: it halves every CONFIDENCE_HALF_LIFE frames
        since the last alignment, and a guess of the predictor counts PREDICTED_CONFIDENCE of a
        measurement of the scene (0 when lost is set by the base class)."""
        decay = 0.5 ** (self.state.since_aligned / CONFIDENCE_HALF_LIFE)
        return self.template_confidence * decay * (PREDICTED_CONFIDENCE if kind == Kind.PREDICTED else 1.0)

    def _update(self, frame) -> Estimate:
        al, st = self.aligner, self.state
        al.stage_ms = self.stage_ms = {}
        st.frame_index += 1
        t0 = time.perf_counter()
        work = al.work_image(frame)
        cut = st.saw(_thumb(work)) < self.hconfig.cut_ncc  # nothing of the last frame is in this one
        t1 = time.perf_counter()
        m, A_seed, occ, is_current = al.coarse(work, st.A)
        t2 = time.perf_counter()
        occ = self._occlusion_at(frame, A_seed, occ)
        t3 = time.perf_counter()
        self.stage_ms.update(prepare=1e3 * (t1 - t0), coarse=1e3 * (t2 - t1), occlusion=1e3 * (t3 - t2))
        if m.score <= 0:  # blank or uniform frame
            occ = 1.0
        gate = self.hconfig.occlusion_gate
        confident = m.score > 0 and (m.score >= self.config.match_threshold or (self.hconfig.continuity and is_current))
        if confident and (occ < gate or self.hconfig.gate_after_alignment):
            A_new = al.align(work, A_seed, None if is_current else al.to_work(st.A)).A_work
            occ_aligned = occ
            if A_new is not None and occ >= gate:  # gated again where the target was aligned (gate_after_alignment)
                grey = None if self.colour_reference is not None else al.occlusion(work, A_new)
                occ_aligned = self._occlusion_at(frame, A_new, grey)
                if occ_aligned >= gate:
                    A_new = None
            if A_new is not None and self._verified(al.to_full(A_new), m, work):
                if self.target_motion is None:
                    self._judge_motion(work, al.to_full(A_new))
                st.aligned(work, al.to_full(A_new), self.sources)
                return Estimate(st.A, Mode.ALIGN, occ_aligned, m.score)
            if occ_aligned >= gate:  # not gated in (where _verified ran, it keeps its own count)
                st.jump_seen(None, 0.0)
        else:
            st.jump_seen(None, 0.0)
        t4 = time.perf_counter()
        est = self._predict(work, occ, m, cut)
        self.stage_ms["sources"] = 1e3 * (time.perf_counter() - t4)
        return est

    def _predict(self, work: np.ndarray, occ: float, m, cut: bool) -> Estimate:
        """The first motion source with a proposal moves the estimate (module docstring); after a scene cut, or too
        long without an alignment, the estimate is lost until the target is aligned again."""
        st = self.state
        if st.after_cut and not cut and self.anchor in self.sources:  # the view may have come back (a full-view
            proposal = self.anchor.propose(work, st)  # occluder, not a cut): only the aligned keyframes can say so
            if proposal is not None:
                st.measured(work, proposal, self.sources)
                return Estimate(st.A, proposal.mode, occ, m.score, self._unaligned_confidence(proposal.kind))
        if cut or st.after_cut or st.since_aligned >= self.hconfig.max_unaligned_frames:
            st.lost(work, self.sources, cut=cut)
            return Estimate(st.A, Mode.LOST, occ, m.score, 0.0)
        for source in self.sources:
            proposal = source.propose(work, st)
            if proposal is None:
                continue
            if proposal.kind == Kind.PREDICTED:
                if proposal.mode == Mode.LOST:
                    st.lost(work, self.sources)
                else:
                    st.predicted(work, proposal.A, self.sources)
            else:
                st.measured(work, proposal, self.sources)
            return Estimate(st.A, proposal.mode, occ, m.score, self._unaligned_confidence(proposal.kind))
        raise AssertionError("the predictor source always proposes")  # pragma: no cover
