"""LoopConfig: the closed loop's settings, each checked on its own when given; what "None" resolves to is
servo/plan.py's, decided once per run."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from hvs_sim import plugins
from hvs_sim.control.feature_filter import FEATURE_FILTER_ALPHA
from hvs_sim.control.laws.ibvs import CONTROLLERS, IBVSConfig
from hvs_sim.control.safety import SafetyConfig
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.render.camera import MAX_STILL_FRAMES
from hvs_sim.servo.parts import (
    GOAL_FRAMES,
    NEAR_GOAL_AUTO,
    NEAR_GOAL_OFF,
    NEAR_GOAL_PX,
    NEAR_GOAL_SCALE,
    TEMPLATE_VIEWS,
)
from hvs_sim.tracking import TRACKER_NAMES
from hvs_sim.validate import check_flags, check_number

LOOP_TRACKERS = (plugins.GROUND_TRUTH, plugins.NO_TRACKER) + TRACKER_NAMES  # the built-ins; plugins beside them
MAX_STEPS = 100_000
IN_VIEW_MARGIN_PX = 2.0  # the target's corners must be this far inside the image at the start
# pose bound for `converged`: a 15 cm target at 0.8 m pins lateral translation and pitch/yaw only
# weakly (a 1° tilt traded against 14 mm of sideways shift moves its corners by ~0.1 px), so the
# bound is stated beside the 0.5 px image threshold rather than derived from it
CONVERGE_MM, CONVERGE_DEG = 10.0, 1.0
GOAL_ROI_INSET_PX = 8  # LoopConfig.roi_inset_px's default with a goal template (6-DOF servo benchmark, README)
MAX_TEMPLATE_GROWTH_PX = 400  # the most a negative roi_inset_px may grow the goal template (it must fit the image)


def option(flag: str, help: str, **argparse_kw) -> dict:
    """A LoopConfig field's command-line option (cliargs.add_config_options adds it under the field's name): its flag,
    its help and argparse's other keywords (type, metavar, choices). `run` takes every one, so a new loop option is one
    edit, here; `bench servo` takes those ServoBenchConfig also carries (a field there, and its way to the episodes)."""
    return {"cli": {"flag": flag, "help": help, **argparse_kw}}


def parse_near_goal_inset(text: str) -> int | str:
    """--near-goal-inset's value: auto, off, or a whole number of px (LoopConfig checks the number)."""
    if text in (NEAR_GOAL_AUTO, NEAR_GOAL_OFF):
        return text
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"expected {NEAR_GOAL_AUTO}, {NEAR_GOAL_OFF} or a negative whole number of px, got {text!r}") \
            from None


@dataclass(frozen=True)
class LoopConfig:
    steps: int = 300
    converge_px: float = 0.5  # mean corner error to s* that counts as converged ...
    hold_steps: int = 10  # ... when held this many consecutive steps
    ibvs: IBVSConfig = field(default_factory=IBVSConfig)
    keep_frames: bool = True  # put the rendered frame in each record (for logging)
    # the evaluation renders (the true occlusion, one segmentation render a step). Off: no render but the
    # camera's; records keep the geometric truth (corner and pose errors, no rendering) and occlusion NaN.
    # Control never reads either: features from the tracker, camera pose from the joints, depth from the
    # tracked scale (IBVSConfig.depth="true" asks the simulator)
    evaluate: bool = True
    # the servo law: "ibvs" (v = −λ L⁺ e), "pbvs" (laws/pbvs.py), "dvs" (photometric, laws/dvs.py; no tracker), all with `ibvs`'s
    # gains, or an outside law (hvs_sim.plugins: a registered name, an entry point, module:callable)
    controller: str = "ibvs"
    # an outside policy (image + joints → camera twist, hvs_sim.plugins) in place of tracker and law (tracker "none")
    policy: str | None = None
    # and the pose must be within these of the reference pose, in the DOFs controlled (ground truth)
    converge_mm: float = CONVERGE_MM
    converge_deg: float = CONVERGE_DEG
    # TEMPLATE_VIEWS, or None: "goal" for a tracker on six DOF, else "start". "goal" is teach-by-showing: the
    # template is cut from the goal image (the arm at the reference pose, the people left out, this run's
    # camera model) and the tracker is seeded at the target's corners in the first frame; the features are
    # then most exact where it matters, at the goal. From the tilted start view the template's corners kept a
    # 0.2–0.3 px bias at the goal, which L's weak direction turns into 4–5° (README, 6-DOF servo benchmark)
    template_from: str | None = field(default=None, metadata=option(
        "--template-from", choices=TEMPLATE_VIEWS,
        help="where the tracker's template comes from: the run's first frame, or the goal image (the camera at the "
             "reference pose, people left out: teach-by-showing), the tracker then seeded at the target's corners in "
             "the first frame (default: goal for a tracker on six DOF, one with the homography warp; else start)"))
    # the template is cut this many pixels inside the target's outline, whose rendering (aliased edge, the
    # flag's side faces and its 4 mm relief above the board) changes from view to view: with the goal template,
    # tracked corners 0.3–0.5 px off near the goal without an inset, 0.02–0.05 px with 8 px. None:
    # GOAL_ROI_INSET_PX with a goal template (less where the box would fall under MIN_ROI), 0 with a start one.
    # Negative (a goal template only): the box grows that many pixels beyond the outline, into the target's
    # surroundings, which must lie in its plane (the wall's other pictures do; the board behind them sits 4 mm back).
    # The wider template pins the pose's weak directions (figures: docs/tuning.md, roi_inset_px)
    roi_inset_px: int | None = field(default=None, metadata=option(
        "--roi-inset", type=int, metavar="PX",
        help="cut the template this many pixels inside the target's outline, which renders differently from view to "
             f"view (default: {GOAL_ROI_INSET_PX} with a goal template, fewer for a target too small for it; 0 with a "
             "start template). Negative, with a goal template: grow it that many pixels into the target's "
             "surroundings, which must lie in its plane (-90: the wall's neighbouring pictures, the 6-DOF loop's most "
             "precise setting, docs/results.md)"))
    # a second, grown goal template (a negative inset, as roi_inset_px) the loop switches to once the tracked corners
    # are within near_goal_px of s* and the grown box is in view: the small template brings the camera near from
    # afar (the grown box may lie out of a tilted start view, where its first alignment fails), the grown one pins
    # the pose's weak directions at the goal. The tracker is re-seeded on it through the corners' homography, and s*,
    # the law and the feature filter start again on its corners. NEAR_GOAL_AUTO (the default): the box grown to
    # NEAR_GOAL_AREA of the goal image (near_goal_growth), where the loop has a tracker on a goal template and the box
    # can grow NEAR_GOAL_MIN_GROWTH_PX; otherwise one template, and run.json says why. None: one template throughout.
    # A number is that growth, and a run it cannot apply to is refused
    near_goal_inset_px: int | str | None = field(default=NEAR_GOAL_AUTO, metadata=option(
        "--near-goal-inset", type=parse_near_goal_inset, metavar="auto|off|PX",
        help="switch to a second goal template, grown beyond the target's outline, once the tracked corners are within "
             "--near-goal-px of the goal's: the default template's robustness from afar, the grown one's precision at "
             "the goal. auto (the default): grown to a quarter of the goal image, where the run tracks a goal template "
             "and the box has room; off: one template; PX (negative): that growth (docs/results.md, the pose bound)"))
    # None: NEAR_GOAL_PX (a number with near_goal_inset_px None is refused)
    near_goal_px: float | None = field(default=None, metadata=option(
        "--near-goal-px", type=float, metavar="PX",
        help=f"mean corner distance to the goal's corners that switches to the near-goal template (default "
             f"{NEAR_GOAL_PX})"))
    # the working scale (DeepLKConfig.scale) of the tracker on the near-goal template: a built-in tracker is built a
    # second time at this scale for it, as its VGG features cost what the template's area does (the intensity
    # refinement stays at full resolution). None: NEAR_GOAL_SCALE for a built-in tracker, an outside one's own
    near_goal_scale: float | None = field(default=None, metadata=option(
        "--near-goal-scale", type=float, metavar="S",
        help=f"track the near-goal template at this working scale (the tracker's working_scale; default {NEAR_GOAL_SCALE} for a "
             "tracker that has one: its VGG features cost what its area does; the intensity refinement stays at full "
             "resolution)"))
    # frames of the still scene averaged into the goal image (Renderer.still_average; 1 = one frame). None:
    # GOAL_FRAMES with a goal template; a number with a start template is refused (it would do nothing)
    goal_frames: int | None = field(default=None, metadata=option(
        "--goal-frames", type=int, metavar="N",
        help="frames of the still goal view averaged into the goal image, as a user teaching the goal averages a few "
             f"grabs: the camera's noise falls ~√N (default {GOAL_FRAMES} with a goal template; a start template has "
             "no goal image)"))
    # α of the feature filter (control/feature_filter.py): the tracked corners blended with where the camera's
    # own motion (forward kinematics) carries the last estimate; 0 = off. None: FEATURE_FILTER_ALPHA for tracked
    # corners on six DOF, off otherwise (exact features need none; the 4-DOF path is the paper's)
    feature_filter: float | None = field(default=None, metadata=option(
        "--feature-filter", type=float, metavar="ALPHA",
        help="α of the filter that blends the tracked corners with where the camera's own motion (the joints' forward "
             f"kinematics) carries the last estimate, in [0, 1]; 0 = off (default {FEATURE_FILTER_ALPHA} for tracked "
             "corners on six DOF, else off)"))
    # track frame k in a second thread while the physics steps and frame k + 1 renders (ServoLoop.run): the step
    # costs about the longer of the two instead of their sum, and frame k's command acts one frame later
    pipeline: bool = False
    # the safety rule (control/safety.py): the twist ramps to zero while the loop does not see the target (lost, a
    # long prediction, features implausible or out of the image) and servoing resumes on a verified alignment; a
    # command that would leave the workspace envelope ends the episode as aborted. For every tracker and law
    safety: SafetyConfig = field(default_factory=SafetyConfig)

    def __post_init__(self):
        if self.controller not in CONTROLLERS:
            plugins.check("controller", self.controller)
        if self.policy is not None:
            plugins.check("policy", self.policy)
        if self.template_from is not None and self.template_from not in TEMPLATE_VIEWS:
            raise choice_error("template_from", self.template_from, TEMPLATE_VIEWS)
        if self.roi_inset_px is not None:
            check_number("roi_inset_px", self.roi_inset_px, -MAX_TEMPLATE_GROWTH_PX, integer=True)
        if self.near_goal_inset_px == NEAR_GOAL_OFF:
            object.__setattr__(self, "near_goal_inset_px", None)
        if self.near_goal_inset_px is not None and self.near_goal_inset_px != NEAR_GOAL_AUTO:
            if isinstance(self.near_goal_inset_px, str):
                raise ConfigError(f"near_goal_inset_px must be {NEAR_GOAL_AUTO!r}, {NEAR_GOAL_OFF!r} or None (one "
                                  f"template), or a negative whole number of px, got {self.near_goal_inset_px!r}")
            check_number("near_goal_inset_px", self.near_goal_inset_px, -MAX_TEMPLATE_GROWTH_PX, -1, integer=True)
            if self.roi_inset_px is not None and self.roi_inset_px < 0:
                raise ConfigError(f"near_goal_inset_px ({self.near_goal_inset_px}) switches to a grown template near "
                                  f"the goal, but roi_inset_px ({self.roi_inset_px}) grows the first one already: give "
                                  "one of them (or an roi_inset_px ≥ 0)")
        if self.near_goal_scale is not None:
            check_number("near_goal_scale", self.near_goal_scale, 0, 1, lo_open=True)
        if self.near_goal_px is not None:
            check_number("near_goal_px", self.near_goal_px, 0, lo_open=True)
        for name, value in (("near_goal_scale", self.near_goal_scale), ("near_goal_px", self.near_goal_px)):
            if value is not None and self.near_goal_inset_px is None:
                raise ConfigError(f"{name} ({value}) sets the near-goal template, which near_goal_inset_px=None turns "
                                  f"off: leave near_goal_inset_px at {NEAR_GOAL_AUTO!r} (or give a growth), or leave "
                                  f"{name} out")
        if self.feature_filter is not None:
            check_number("feature_filter (alpha)", self.feature_filter, 0, 1)
        if self.goal_frames is not None:
            check_number("goal_frames", self.goal_frames, 1, MAX_STILL_FRAMES, integer=True)
            if self.template_from == "start":
                raise ConfigError(f"goal_frames ({self.goal_frames}) averages frames into a goal image, but "
                                  "template_from='start' takes the template from the first frame: give one of them")
        if self.policy is not None and self.controller != "ibvs":
            raise ConfigError(f"a policy ({self.policy!r}) replaces the servo law: leave controller "
                              f"({self.controller!r}) at its default")
        if not (self.converge_mm > 0 and self.converge_deg > 0):
            raise ConfigError(f"converge_mm and converge_deg must be > 0, got {self.converge_mm}, {self.converge_deg}")
        if isinstance(self.steps, bool) or not isinstance(self.steps, (int, np.integer)) or not 1 <= self.steps <= MAX_STEPS:
            raise ConfigError(f"steps must be an int in [1, {MAX_STEPS}], got {self.steps!r}")
        check_number("converge_px", self.converge_px, 0, lo_open=True)
        check_number("hold_steps", self.hold_steps, 1, integer=True)
        check_number("converge_mm", self.converge_mm, 0, lo_open=True)
        check_number("converge_deg", self.converge_deg, 0, lo_open=True)
        check_flags(self, ("keep_frames", "evaluate", "pipeline"))
        if not isinstance(self.safety, SafetyConfig):
            raise ConfigError(f"safety must be a SafetyConfig (hvs_sim.control.safety), got {type(self.safety).__name__}")

    @property
    def near_goal_within_px(self) -> float:
        """near_goal_px resolved: NEAR_GOAL_PX where it is not given."""
        return NEAR_GOAL_PX if self.near_goal_px is None else float(self.near_goal_px)


def loop_options() -> list[tuple[str, dict]]:
    """(field name, its command-line option) of each LoopConfig field that has one (`option`)."""
    return [(f.name, f.metadata["cli"]) for f in fields(LoopConfig) if "cli" in f.metadata]
