"""The hybrid tracker's settings (HybridConfig) and the tuned constants they default to, apart from the tracker
(tracking/hybrid.py) that reads them: what the hybrid does with each is said there and in docs/tuning.md."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.aligner_config import DeepLKConfig
from hvs_sim.tracking.background import CLEAR_OP, BackgroundConfig
from hvs_sim.tracking.feature_lk import LKConfig
from hvs_sim.tracking.predictors import PREDICTORS
from hvs_sim.validate import check_flags, check_number

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


def hybrid_deep_config(residual: bool = False, warp: str = "similarity") -> DeepLKConfig:
    """The hybrid's default alignment settings: the fast LK above (for `warp`), or, with the residual regressor,
    deep_lk's (pool2 → pool1 → conv1_2 on all channels)."""
    if residual:
        return DeepLKConfig()
    lk = HYBRID_LK_HOMOGRAPHY if warp == "homography" else HYBRID_LK
    return DeepLKConfig(lk=lk, margin=HYBRID_MARGIN, always_search_as_taken=False, search_near_first=True,
                        intensity_smooth="frame")


TARGET_MOTIONS = ("static", "moving", "auto")  # HybridConfig.target_motion

# predictor frames since the last alignment or re-anchoring after which the estimate is no longer the surroundings'
# (HybridConfig.surroundings_veto_frames): half a second of guesses. A shirt printed with the scene's texture left the
# chain unmeasured for 6 frames before its far match came (natural benchmark, `lookalike`); a jump within the
# predictor's possible drift is accepted anyway (HybridConfig.reacquire_px, background_gate_px)
SURROUNDINGS_GUESSES = 15
# a re-acquisition (HybridTracker._reacquisition_verified): an alignment after the target was lost, after a cut, or
# after this many frames without an alignment (half a second) must pass every check, not the score alone
REACQUIRE_AFTER = 15
# ... one of them: the template's NCC with the whole aligned patch (at least APPEARANCE_MIN_SHOWN of it in the frame),
# within APPEARANCE_SLACK of what this track's own confident alignments measured
APPEARANCE_SLACK = 0.15
# the target's surroundings overrule the chain's veto only where they agree with the far match by this much more than
# with the estimate (HybridConfig.context_agree): both rings share the picture's overall layout
CONTEXT_MARGIN = 0.3
APPEARANCE_MIN_SHOWN = 0.6
APPEARANCE_HISTORY = 30  # confident alignments whose appearance NCC sets that reference (their median)
APPEARANCE_RECORD_OCC = 0.1  # an alignment with OP_t up to this is confident enough to set it
# the perspective report (HybridConfig.perspective) is measured on an aligned frame with OP_t up to this: the intensity
# refinement has no robust weights, and a hand's defocused edge over 18 % of the target pulled it 2.7 px, which the
# report then carried through the whole occlusion (photos' dev split, `hand` on china of seed 7)
PERSPECTIVE_MAX_OCC = 0.1
# an alignment is checked against the surroundings (HybridConfig.pull_check) in full where OP_t there is over this (the
# target partly covered; a clear hand-held view reads up to ~0.15 from blur and noise, background.CLEAR_OP; the full
# measurement from 0.1 peeked on a fifth of the photos' dev frames, 4.35 -> 5.28x the ECC reference's time), below it
# in a quick hop (`pull_check_clear`), and taken for pulled where it lies over PULL_CHECK_PX from their pose
PULL_CHECK_OCC = CLEAR_OP
PULL_CHECK_PX = 1.0
# ... and (`pull_check_carried`) a miss over this is no error of the surroundings' measurement: their hops missed a
# hidden target by up to 1.5-2 px, chained over a few frames (pull_evidence below), twice the 2 px a frame is scored by
PULL_FAR_PX = 4.0
# ... and where OP_t reads the target clear (`pull_check_clear`), only where the ring of picture around it, from the
# last alignment to this one, correlates under this (evidence.ring_steadiness): something came into the surroundings or
# the alignment left them. On the photos' dev seed 61 it skipped 92 % of those checks and none that refused a pull
PULL_RING_STEADY = 0.95
# ... and the pose is reported with the median of the last this many (HybridTracker._reported): on a clear sequence
# whose tilted view biased the similarity by up to 3.8 px (china, seed 7) the correction moved by at most 0.9 px
# from one measurement to the next, while a look-alike pulled one frame's 3.4 px
PERSPECTIVE_HISTORY = 5
LOST_NOTES = 5  # `lost` episodes explained in the tracker's notes, one line each; later ones are counted
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
    # ... or from where the scene's measured motion carries the last measured position (SceneMotionSource._passes): a
    # hand-held view sweeping 5-7 px a frame was otherwise refused on every frame and the estimate fell behind (the
    # photos' dev split, `camo`: 100-225 px off under the look-alike person); False: from the estimate alone
    background_gate_continues: bool = True
    # ... and the gate, around the estimate and that continuation, widens by how much the target's per-frame motion
    # changed between the last consecutive alignments, beyond the half of it left for that (_passes): hand-held at 10 fps
    # the view's per-frame motion changed by 4-6 px from one frame to the next, and the gate refused every correct
    # measurement while the camera's inertia carried the estimate away (docs/results.md, a view three times faster);
    # False: a fixed gate
    background_gate_sway: bool = True
    # frames for which, while the surroundings give nothing the gate takes, the estimate is carried on by the scene's
    # last measured per-frame motion (the camera's inertia) before the predictor guesses: as a coat swept in, the GRU
    # held the estimate still while the view moved 3-6 px a frame, and the chain restarted from it 27 px off (photos'
    # dev split, `long`); 0: the predictor guesses from the first such frame, as in the paper
    scene_inertia_frames: int = 5
    background_config: BackgroundConfig = field(default_factory=BackgroundConfig)
    # a similarity hybrid reports the target's perspective: on aligned frames the homography near the similarity is
    # refined on the full-resolution grey template (Aligner.perspective), and the pose is reported with the median of
    # the last corrections, on unaligned frames too (HybridTracker._reported). The estimate LK and the motion sources
    # carry stays the similarity. False: the similarity is reported, as in the paper. Moot with warp="homography",
    # whose alignment is the plane's own
    perspective: bool = True
    # ... and the feature LK then aligns the similarity under that perspective (the family S·C, C the reported
    # correction less its own similarity; Aligner.shape): a similarity alone fits a tilted target best at a place
    # that depends on which part of it is visible, so an occluder over part of it moved the alignment by pixels with
    # no pull of its texture at all (photos' dev split, `long` ascent). False: the similarity alone, as in the paper.
    # None: on, unless the residual regressor runs (trained on the similarity LK's answers; both together are refused)
    lk_perspective: bool | None = None
    # an alignment of a partly covered static target that the surroundings' motion since the frame before contradicts
    # (PULL_CHECK_*) and that does not fit the template better than their pose (pull_evidence) was pulled by the
    # occluder: the frame is not aligned, and the surroundings carry the estimate (HybridTracker._pulled). False: all are taken
    pull_check: bool = True
    # ... also where OP_t says the target shows clear but the ring of picture around it changed since the last
    # alignment (PULL_RING_STEADY), the surroundings then measured in a quick hop (SceneMotionSource.quick_peek): a
    # person wearing the target's own picture is no occluder to OP_t, and as they walked in over the target the
    # alignment moved with them 4-5 px a frame (photos' dev split, `camo`). False: only where OP_t is over
    # PULL_CHECK_OCC (docs/results.md, `hybrid_covered_pull`)
    pull_check_clear: bool = True
    # ... also on an alignment of a covered target after frames the surroundings alone carried it (none guessed), where
    # it lies over PULL_FAR_PX from their pose; and a miss over PULL_FAR_PX counts as evidence for the alignment only
    # where the template tells the two poses apart by more than the better fit's own residual (Aligner.shows_clearly's
    # `discernible`): a featureless target shows as well 12 px to the side, and as a coat came over 58 % of it an
    # alignment there was taken, and chained for 150 frames (photos' dev split, `long` ascent). False: only on the
    # frame after an alignment, any better fit (docs/results.md, `hybrid_aligned_pull`)
    pull_check_carried: bool = True
    # a static target's alignment after 1 to REACQUIRE_AFTER - 1 frames the surroundings alone carried (none guessed)
    # is not taken where its scale departs from the estimate's by over this share: over a few frames the surroundings
    # measure the view's scale change. On the frame after an alignment the scale changed by 0.58 % at the 99th
    # percentile (photos' dev split, seed 70's `clear` and `hand`, 1 343 alignments); an alignment on a repetitive roof
    # 4.6 % under it was taken, and the template rectified at that scale matched nowhere for 150 frames. 0: off
    # (docs/results.md, `hybrid_free_scale`)
    carried_scale_step: float = 0.02
    # ... taken where the frame shows the template better at the alignment than at the surroundings' pose by more than
    # this share of what the template itself tells the two poses apart by (Aligner.shows_clearly; where the alignment
    # is right, about all of it). 0: any better fit. 0.5 refused a coat's 4 px pull on a smooth photo that fitted a
    # little better, but also right alignments where the surroundings' hop was 1.5 px off (docs/results.md)
    pull_evidence: float = 0.0
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
    # with a look-alike in view (the match not unique), a static target's alignment (a re-acquisition near where the
    # surroundings put it, or one within REACQUIRE_AFTER frames of the last) allows reacquire_drift_px only per frame
    # the predictor guessed, not per frame their motion was measured on: a chain measured for 85 frames stayed within
    # 0.6 px of the target, and a person wearing its picture 37 px away was within the 50 px the flat allowance gave;
    # 12 measured frames let in a copy 12.6 px away (photos' dev split, `camo` ascent). False: per frame
    lookalike_drift: bool = True
    # a static target's far jump that the surroundings contradict: while the frames since the last alignment were
    # measured on the surroundings (at most SURROUNDINGS_GUESSES predictor guesses, no seed), they say where the
    # target is, and a unique match far from there is a look-alike (clothing printed with the scene's own texture,
    # paused over the target), refused until seen on this many consecutive frames (3 s at 30 Hz: a chain that went
    # wrong is not held forever). 0: off (docs/results.md, harder occluders)
    surroundings_veto_frames: int = 90
    # ... unless the target's own surroundings overrule the chain (`context_check`, HybridTracker._context_overrules): the ring of picture
    # around the template, as its view showed it, agrees with the ring around the far match (NCC of the blurred rings,
    # evidence.context_agreement) by at least this, and by CONTEXT_MARGIN more than with the ring around the estimate.
    # A chain that took a leaving coat's motion for the scene's put the target 125 px off, and the visible target's
    # unique match (ring 0.99 against -0.2 at the estimate) was held back to the end (photos' dev split at 10 fps,
    # `long`); on the natural set's shirts printed with the scene the refused far matches' rings read at most 0.72.
    # False: the veto holds on the frame count alone
    context_check: bool = True
    context_agree: float = 0.8
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
        if self.lk_perspective is None:
            object.__setattr__(self, "lk_perspective", not self.deep.residual)
        check_flags(self, ("continuity", "colour_occlusion", "gate_after_alignment", "background", "reanchor",
                           "verify_reacquisition", "background_gate_continues", "background_gate_sway", "perspective",
                           "pull_check", "pull_check_clear", "pull_check_carried", "lk_perspective", "lookalike_drift",
                           "context_check"))
        check_number("pull_evidence", self.pull_evidence, 0.0, 1.0)
        check_number("carried_scale_step", self.carried_scale_step, 0.0, 1.0)
        check_number("context_agree", self.context_agree, -1.0, 1.0)
        if self.lk_perspective and self.deep.residual:
            raise ConfigError("lk_perspective=True cannot run with the residual regressor, which was trained on the "
                              "similarity LK's answers: leave lk_perspective unset (off with the regressor) or set it False")
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
        check_number("scene_inertia_frames", self.scene_inertia_frames, 0, integer=True)
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
