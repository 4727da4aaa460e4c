"""The closed loop: render → track → control → step physics, one record per step.

Logging and plots only read the records. A tracker exception or non-finite output stops the arm
for that step (zero twist) and is written into the record; the loop goes on.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import torch

from hvs_sim import plugins
from hvs_sim.control.arm import ArmDriver, JointCommand
from hvs_sim.control.feature_filter import FEATURE_FILTER_ALPHA, FeatureFilter
from hvs_sim.control.ibvs import (
    CONTROLLERS,
    DOF_NAMES,
    TRACKED_6DOF_DAMPING,
    ControlOutput,
    IBVSConfig,
    IBVSController,
    bound_twist,
    condition_number,
    dofs_for,
    matrix_rank,
)
from hvs_sim.control.pbvs import PBVSController
from hvs_sim.control.protocol import ControlInput, PolicyInput, scale_depths
from hvs_sim.control.safety import Envelope, SafetyConfig, SafetyGate
from hvs_sim.errors import ConfigError, HvsError, InputError, StateError, choice_error
from hvs_sim.loopparts import (
    GOAL_FRAMES,
    NEAR_GOAL_AREA,
    NEAR_GOAL_AUTO,
    NEAR_GOAL_MIN_GROWTH_PX,
    NEAR_GOAL_OFF,
    NEAR_GOAL_PX,
    NEAR_GOAL_SCALE,
    TEMPLATE_VIEWS,
    Capture,
    Episode,
    Measured,
    ResolvedLoop,
    Stopwatch,
    Template,
    frozen,
    lap,
)
from hvs_sim.render.camera import CameraPose
from hvs_sim.render.renderer import MAX_STILL_FRAMES, Renderer
from hvs_sim.runstats import MODES, RunStats, summarize_run  # noqa: F401  (re-exported: the loop's summary)
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.scene.world import Scene
from hvs_sim.sensor import distort_points, undistort_points
from hvs_sim.tracking import TRACKER_NAMES, Track, Tracker, make_tracker
from hvs_sim.tracking.frames import MIN_ROI, inset_roi, roi_corners, roi_from_corners
from hvs_sim.tracking.warp import apply as apply_warp
from hvs_sim.tracking.warp import perspective_transform
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
    # the servo law: "ibvs" (v = −λ L⁺ e), "pbvs" (pbvs.py), "dvs" (photometric, dvs.py; no tracker), all with `ibvs`'s
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
    template_from: str | None = None
    # the template is cut this many pixels inside the target's outline, whose rendering (aliased edge, the
    # flag's side faces and its 4 mm relief above the board) changes from view to view: with the goal template,
    # tracked corners 0.3–0.5 px off near the goal without an inset, 0.02–0.05 px with 8 px. None:
    # GOAL_ROI_INSET_PX with a goal template (less where the box would fall under MIN_ROI), 0 with a start one.
    # Negative (a goal template only): the box grows that many pixels beyond the outline, into the target's
    # surroundings, which must lie in its plane (the wall's other pictures do; the board behind them sits 4 mm back).
    # The wider template pins the pose's weak directions (figures: docs/tuning.md, roi_inset_px)
    roi_inset_px: int | None = None
    # a second, grown goal template (a negative inset, as roi_inset_px) the loop switches to once the tracked corners
    # are within near_goal_px of s* and the grown box is in view: the small template brings the camera near from
    # afar (the grown box may lie out of a tilted start view, where its first alignment fails), the grown one pins
    # the pose's weak directions at the goal. The tracker is re-seeded on it through the corners' homography, and s*,
    # the law and the feature filter start again on its corners. NEAR_GOAL_AUTO (the default): the box grown to
    # NEAR_GOAL_AREA of the goal image (near_goal_growth), where the loop has a tracker on a goal template and the box
    # can grow NEAR_GOAL_MIN_GROWTH_PX; otherwise one template, and run.json says why. None: one template throughout.
    # A number is that growth, and a run it cannot apply to is refused
    near_goal_inset_px: int | str | None = NEAR_GOAL_AUTO
    near_goal_px: float | None = None  # None: NEAR_GOAL_PX (a number with near_goal_inset_px None is refused)
    # the working scale (DeepLKConfig.scale) of the tracker on the near-goal template: a built-in tracker is built a
    # second time at this scale for it, as its VGG features cost what the template's area does (the intensity
    # refinement stays at full resolution). None: NEAR_GOAL_SCALE for a built-in tracker, an outside one's own
    near_goal_scale: float | None = None
    # frames of the still scene averaged into the goal image (Renderer.still_average; 1 = one frame). None:
    # GOAL_FRAMES with a goal template; a number with a start template is refused (it would do nothing)
    goal_frames: int | None = None
    # α of the feature filter (control/feature_filter.py): the tracked corners blended with where the camera's
    # own motion (forward kinematics) carries the last estimate; 0 = off. None: FEATURE_FILTER_ALPHA for tracked
    # corners on six DOF, off otherwise (exact features need none; the 4-DOF path is the paper's)
    feature_filter: float | None = None
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


@dataclass
class StepRecord:
    step: int
    time: float
    frame: np.ndarray | None
    track: Track | None
    mode: str  # tracker mode ("align" | "predict" | "lost"), or "fault"
    features: np.ndarray  # (4, 2) corners the controller used
    gt_features: np.ndarray  # (4, 2) where those corners truly are
    desired: np.ndarray  # (4, 2) s*
    error_px: float  # ground-truth mean corner error to s*
    tracker_error_px: float  # mean distance between tracked and true corners
    occlusion: float  # true occlusion fraction
    twist: np.ndarray  # (6,) camera frame
    qdot: np.ndarray
    q: np.ndarray
    camera: CameraPose
    gain: float
    saturated: bool
    limit_blocked: tuple[int, ...]
    fault: str | None
    timings: dict[str, float]  # ms per stage
    # the camera's pose error to the reference pose (Scene.pose_error: x, y, z mm; about x, y, z deg), truth
    pose_error: np.ndarray = field(default_factory=lambda: np.zeros(6))
    singular_values: np.ndarray = field(default_factory=lambda: np.zeros(0))  # of the controlled columns of L
    dofs: tuple[str, ...] = DOF_NAMES  # the DOFs the controller commands
    target_in_view: bool = True  # all four true target corners inside the image
    damping: float = 0.0  # the IBVS damping the loop used (IBVSConfig.damping, resolved)
    feature_filter: float = 0.0  # the feature filter's α the loop used (LoopConfig.feature_filter, resolved; 0 = off)
    filter_restarted: bool = False  # the feature filter restarted at this measurement (FeatureFilter.gate_px)
    # where the template came from, its inset and the frames averaged into a goal image (LoopConfig, resolved)
    template: tuple[str, int, int | None] = ("start", 0, None)
    # wall ms of the step when its stages overlap (LoopConfig.pipeline): from the end of the step before (so the
    # consumer's time, e.g. logging, counts in the next step) to this record; a pipelined step's render,
    # ground_truth and physics are those of the next frame, made while this one was tracked (0 on the last step).
    # None: the stages ran one after another and their sum is the step's time
    wall_ms: float | None = None
    controlled_pose_error: tuple[float, float] = (0.0, 0.0)  # (mm, deg) of pose_error in those DOFs
    people: list = field(default_factory=list)  # (feet position, orientation) of each person
    # the safety rule (LoopConfig.safety): why it held the arm this step (None: the law's twist was followed), and
    # why the episode ended here, when the next command would have left the workspace envelope
    held_because: str | None = None
    aborted: str | None = None
    arm: tuple | None = None  # (positions (k, 3), orientations (k, 3, 3)) of the arm's meshes (Scene.arm_meshes)

    @property
    def condition(self) -> float | None:
        """Condition number of the controlled columns of L (None: no control this step, or rank-deficient)."""
        return condition_number(self.singular_values)

    @property
    def rank(self) -> int | None:
        return matrix_rank(self.singular_values)


def corners_in_view(px: np.ndarray, camera, margin: float = 0.0) -> bool:
    """Whether all points (pixels) are finite and at least `margin` inside a camera's image."""
    hi = np.array([camera.width - 1, camera.height - 1]) - margin
    return bool(np.all(np.isfinite(px)) and np.all((px >= margin) & (px <= hi)))


def box_in_view(roi, camera) -> bool:
    """Whether a template box lies as far inside a camera's image as the switch to a grown template asks of its
    corners in the frame (ServoLoop._near_goal_due: IN_VIEW_MARGIN_PX), so that a run given it can switch."""
    return corners_in_view(roi_corners(roi), camera, IN_VIEW_MARGIN_PX)


def near_goal_growth(outline, camera) -> tuple[int | None, str | None]:
    """The automatic near-goal template (LoopConfig.near_goal_inset_px = NEAR_GOAL_AUTO): the growth (px, negative
    as an inset) that takes the target's outline box in the goal image to NEAR_GOAL_AREA of the image, alike on every
    side, or less where the box would run out of the image (box_in_view). (None, why) where that is under
    NEAR_GOAL_MIN_GROWTH_PX: the one template is then nearly all there is to take."""
    x, y, w, h = (int(v) for v in outline)
    share = w * h / (camera.width * camera.height)
    # (w + 2g)(h + 2g) = NEAR_GOAL_AREA · W · H, the positive root; no more than a growth given may be
    g = int(np.floor((-(w + h) + np.sqrt((w + h) ** 2 + 4 * (NEAR_GOAL_AREA * camera.width * camera.height - w * h)))
                     / 4)) if share < NEAR_GOAL_AREA else 0
    g = min(g, MAX_TEMPLATE_GROWTH_PX)
    if g < NEAR_GOAL_MIN_GROWTH_PX:
        return None, (f"the target's box already holds {share:.0%} of the goal image (the near-goal template grows it "
                      f"to {NEAR_GOAL_AREA:.0%})")
    while g >= NEAR_GOAL_MIN_GROWTH_PX and not box_in_view(inset_roi((x, y, w, h), -g), camera):
        g -= 1
    if g < NEAR_GOAL_MIN_GROWTH_PX:
        return None, (f"the target's box lies within {NEAR_GOAL_MIN_GROWTH_PX} px of the goal image's edge: no room "
                      "to grow the near-goal template")
    return -g, None


def check_start_in_view(scene: Scene, renderer: Renderer) -> None:
    """ConfigError unless all four target corners are inside the image from the scenario's start pose."""
    start_pos, start_R = scene.start_pose()
    px = renderer.project(CameraPose(start_R, start_pos), scene.target_corners_world())
    cam = scene.scenario.camera
    if not corners_in_view(px, cam, IN_VIEW_MARGIN_PX):
        raise ConfigError(f"from the start offset {scene.scenario.start_offset_text} the target is not fully in view "
                          f"(its corners at {np.round(px, 1).tolist()} px in a {cam.width}×{cam.height} image): "
                          "give a smaller offset")


def check_start_pose(scenario: Scenario) -> None:
    """ConfigError when the arm cannot reach the scenario's start pose or the target is not fully in view
    from it (builds the scene, renders nothing)."""
    scene = Scene(scenario)
    check_start_in_view(scene, Renderer(scene))


def check_combination(tracker: str, config: LoopConfig, image_law: bool | None = None) -> None:
    """The rules between the tracker's name and the loop's settings (ServoLoop applies them, and a sweep checks its
    whole grid with them before it runs). `image_law`: whether the law reads only the images; None: what the settings
    say without building the law (dvs does; an outside law is given the benefit of the doubt)."""
    unknown = image_law is None and config.controller not in CONTROLLERS  # an outside law not built: either may hold
    if image_law is None:
        image_law = config.controller == "dvs"
    if config.policy is not None and tracker != plugins.NO_TRACKER:
        raise ConfigError(f"a policy ({config.policy!r}) replaces tracker and law: give tracker 'none', not "
                          f"{tracker!r}")
    if tracker == plugins.NO_TRACKER and config.policy is None and not (image_law or unknown):
        raise ConfigError(f"tracker 'none' needs a law that reads only the images (dvs, or an outside law with "
                          f"uses_features = False) or a policy; controller {config.controller!r} needs features")
    if image_law and tracker != plugins.NO_TRACKER:
        raise ConfigError(f"controller {config.controller!r} reads the images, not tracked features: give tracker "
                          f"'none', not {tracker!r}")
    if tracker == plugins.GROUND_TRUTH:
        for name, value in (("feature_filter", config.feature_filter), ("goal_frames", config.goal_frames)):
            if value:
                raise ConfigError(f"{name} ({value}) applies to a tracker's corners; ground_truth features have "
                                  f"no noise to filter and no template: leave {name} out")


def template_view(template_from: str | None, tracked_6dof: bool) -> str:
    """LoopConfig.template_from resolved: as given, else "goal" for tracked corners on six DOF, else "start"."""
    return template_from or ("goal" if tracked_6dof else "start")


def working_scale(tracker) -> float | None:
    """A tracker's working scale (DeepLKConfig.scale), None where it has none (ECC, an outside tracker, no tracker)."""
    return getattr(getattr(tracker, "config", None), "scale", None)


def loop_tracker(tracker: str, settings: dict) -> Tracker | plugins.ExternalTracker | None:
    """The closed loop's tracker by name or plugin reference with its settings (None: the ground_truth oracle, or
    no tracker). Built before the scene, so a bad name or setting costs no rendering."""
    if tracker in (plugins.GROUND_TRUTH, plugins.NO_TRACKER):
        if settings:
            raise ConfigError(f"{tracker} takes no tracker settings, got {sorted(settings)}")
        return None
    if tracker in TRACKER_NAMES:
        return make_tracker(tracker, **settings)
    return plugins.build("tracker", tracker, **settings)


class ServoLoop:
    """One closed-loop episode of a scenario with the arm mount and a named tracker."""

    def __init__(self, scenario: Scenario, tracker: str = "deep_lk", config: LoopConfig = LoopConfig(), **tracker_config):
        if scenario.mount != "arm":
            raise ConfigError(f"the closed loop needs mount='arm', got {scenario.mount!r}")
        # an outside law or policy, built before the scene (and checked with the tracker's name before the tracker)
        self.law = None if config.controller in CONTROLLERS else plugins.build("controller", config.controller)
        self.policy = None if config.policy is None else plugins.build("policy", config.policy)
        self.image_law = config.controller == "dvs" or (self.law is not None and not self.law.uses_features)
        check_combination(tracker, config, self.image_law)
        self.tracker = loop_tracker(tracker, tracker_config)
        self.scenario, self.tracker_name, self.config = scenario, tracker, config
        self.oracle = tracker == plugins.GROUND_TRUTH
        self.resolved = self._resolve(tracker, config)
        self.near_goal_tracker = None  # the tracker on the near-goal template, when it is another (near_goal_scale)
        if self.resolved.near_goal_scale is not None:
            self.near_goal_tracker = make_tracker(tracker, **{**tracker_config, "scale": self.resolved.near_goal_scale})
        self.near_goal_growth: int | None = None  # the near-goal template's growth as step 0 decided it
        self.near_goal_off = self.resolved.near_goal_off  # why there is none, where NEAR_GOAL_AUTO did not apply
        # what a law's failure may raise and the run records as a fault: the built-ins raise HvsError (PBVS on a
        # degenerate quad); an outside method anything
        self._law_errors = Exception if self.law is not None or self.policy is not None else HvsError
        self.scene = Scene(scenario)
        self.renderer = Renderer(self.scene)
        self.arm = ArmDriver(self.scene)
        # desired flag corners: the target seen from the reference pose (centred, at the standoff)
        ref_pos, ref_R = self.scene.reference_pose()
        self.flag_desired = self.renderer.project(CameraPose(ref_R, ref_pos), self.scene.target_corners_world())
        self.desired_depth = float(scenario.standoff)
        check_start_in_view(self.scene, self.renderer)
        self.ibvs_config = dataclasses.replace(config.ibvs, damping=self.resolved.damping)
        # the camera's frames are rendered only when something reads them: a tracker, a law on the images (or an
        # outside one), a policy, or the records (the recording, the figures); the oracle's features and the
        # evaluation come from geometry and segmentation, so a ground-truth run renders no frame at all
        self.renders_frames = bool(self.tracker is not None or self.policy is not None or self.law is not None
                                   or self.image_law or config.keep_frames)

    def near_goal_plan(self, switched_at: int | None) -> dict | None:
        """run.json's near_goal: the grown template as this run had it (None: LoopConfig.near_goal_inset_px=None)."""
        c = self.config
        if c.near_goal_inset_px is None:
            return None
        on = self.near_goal_off is None
        return {"inset_px": self.near_goal_growth, "auto": c.near_goal_inset_px == NEAR_GOAL_AUTO,
                "within_px": c.near_goal_within_px if on else None,
                "scale": (self.resolved.near_goal_scale or working_scale(self.tracker)) if on else None,
                "off": self.near_goal_off, "switched_at_step": switched_at,
                "note": "the step from which the grown template's corners were the features (null: never switched); "
                        "off: why the run kept one template"}

    # the resolved settings under the names the rest of the package reads
    warp = property(lambda self: self.resolved.warp)
    dofs = property(lambda self: self.resolved.dofs)
    filter_alpha = property(lambda self: self.resolved.filter_alpha)
    template_from = property(lambda self: self.resolved.template_from)
    goal_frames = property(lambda self: self.resolved.goal_frames)

    def _resolve(self, tracker: str, config: LoopConfig) -> ResolvedLoop:
        """LoopConfig's None settings decided once, from the tracker, the law and the DOFs the features observe."""
        # the DOFs the features observe: ground truth and a homography tracker give perspective corners
        warp = "homography" if self.tracker is None else self.tracker.warp
        declared = (self.policy.dofs if self.policy is not None else self.law.dofs if self.law is not None else None)
        dofs = tuple(config.ibvs.dofs or declared or dofs_for(warp))
        tracked_6dof = self.tracker is not None and len(dofs) == 6
        damping = config.ibvs.damping
        if damping is None:  # exact features need none; tracked ones on six DOF do (IBVSConfig.damping)
            damping = TRACKED_6DOF_DAMPING if tracked_6dof and config.controller in ("ibvs", "pbvs") else 0.0
        alpha = config.feature_filter
        alpha = (FEATURE_FILTER_ALPHA if tracked_6dof else 0.0) if alpha is None else float(alpha)
        can_seed = getattr(self.tracker, "can_seed", True)  # an outside tracker without seed(A): its first frame
        template_from = template_view(config.template_from, tracked_6dof and can_seed)
        if self.tracker is None and not self.oracle:  # a law on the images or a policy: they compare with the goal
            if config.template_from == "start":
                raise ConfigError("a photometric law or a policy compares the frames with the goal image: leave "
                                  "template_from out (or give 'goal')")
            template_from = "goal"
        if template_from == "goal" and not can_seed:
            raise ConfigError(f"tracker {tracker!r} has no seed(A), so it cannot take its template from the goal image "
                              "and be placed on the first frame: use template_from='start'")
        if template_from == "start" and config.goal_frames is not None:
            raise ConfigError(f"goal_frames ({config.goal_frames}) averages frames into a goal image, but this run's "
                              "template comes from its first frame (template_from='start'): leave goal_frames out, or "
                              "use template_from='goal'")
        if template_from == "start":
            goal_frames = None
        elif self.oracle:  # the oracle takes only the target's corners from a goal image: one frame
            goal_frames = 1
        else:
            goal_frames = config.goal_frames or GOAL_FRAMES
        inset = config.roi_inset_px  # default_inset's answer, where it needs no goal image
        if inset is None and (template_from == "start" or self.oracle):
            inset = 0
        if inset is not None and inset < 0 and template_from == "start":
            raise ConfigError(f"roi_inset_px {inset} grows the template into the target's surroundings, which only a "
                              "goal template may take in: this run's template comes from its first frame (give "
                              "template_from='goal', or an inset ≥ 0)")
        if config.ibvs.depth == "true" and inset is not None and inset < 0:
            raise ConfigError("depth='true' gives IBVS the depths of the target's own corners; a grown template's "
                              "corners lie beyond them, in its plane: leave depth at 'scale' (the tracked scale)")
        near_goal, near_off, near_scale = self._resolve_near_goal(tracker, config, template_from, inset)
        return ResolvedLoop(warp, dofs, damping, alpha, template_from, goal_frames, inset, near_goal, near_off,
                            near_scale)

    def _resolve_near_goal(self, tracker: str, config: LoopConfig, template_from: str,
                           inset: int | None) -> tuple[int | str | None, str | None, float | None]:
        """(the near-goal template's growth: a number, NEAR_GOAL_AUTO for step 0 to decide, or None; why there is
        none where NEAR_GOAL_AUTO cannot apply; the working scale a second tracker is built at, None: the loop's
        own). A number the run cannot apply is refused."""
        near = config.near_goal_inset_px
        if near is None:
            return None, None, None
        why = None
        if self.tracker is None:
            why = f"tracker {tracker!r} has no template"
        elif template_from != "goal":
            why = "this run's template comes from its first frame"
        elif config.ibvs.depth == "true":
            why = ("depth='true' gives IBVS the depths of the target's own corners, and a grown template's corners lie "
                   "beyond them")
        elif inset is not None and inset < 0:
            why = f"roi_inset_px ({inset}) grows the first template already"
        elif near == NEAR_GOAL_AUTO and not getattr(self.tracker, "near_goal", True):
            why = (f"{tracker!r} declines the near-goal template (its `near_goal` is False; give near_goal_inset_px "
                   "a growth to switch it anyway)")
        if why is not None:
            if near != NEAR_GOAL_AUTO:
                raise ConfigError(f"near_goal_inset_px ({near}) switches a tracker to a template grown in the goal "
                                  f"image near the goal, but {why}")
            given = [n for n in ("near_goal_scale", "near_goal_px") if getattr(config, n) is not None]
            if given:
                raise ConfigError(f"{given[0]} sets the near-goal template, but this run has none: {why}")
            return None, why, None
        scale = config.near_goal_scale
        # a built-in tracker with a working scale is built again at the near-goal one; any other tracker is its own
        own = working_scale(self.tracker) if tracker in TRACKER_NAMES else None
        if own is None:
            if scale is not None:
                raise ConfigError(f"near_goal_scale builds a built-in tracker again at another working scale; "
                                  f"{tracker!r} is not one with a working scale (those of "
                                  f"{', '.join(TRACKER_NAMES)} that take `scale`): leave near_goal_scale out")
            return near, None, None
        scale = NEAR_GOAL_SCALE if scale is None else float(scale)
        return near, None, (None if abs(own - scale) < 1e-12 else scale)

    def controlled_pose_error(self, pose_error: np.ndarray) -> tuple[float, float]:
        """(mm, deg) of the pose error in the DOFs this loop controls."""
        cols = [DOF_NAMES.index(d) for d in self.dofs]
        lin, ang = [c for c in cols if c < 3], [c for c in cols if c >= 3]
        return float(np.linalg.norm(pose_error[lin])), float(np.linalg.norm(pose_error[ang]))

    def true_depths(self) -> np.ndarray:
        """Depth (m) of each target corner in the camera frame, from the simulator (IBVSConfig.depth="true")."""
        return self.renderer.camera_pose().to_camera(self.scene.target_corners_world())[:, 2]

    def _pinhole(self, pts: np.ndarray) -> np.ndarray:
        """Image points with the lens distortion taken out, as a calibrated camera would give IBVS its features
        (the interaction matrix holds for a pinhole); unchanged for a camera without distortion."""
        dist = self.renderer.sensor.distortion
        return undistort_points(self.renderer.K, dist, pts) if dist else pts

    def _distort(self, pts: np.ndarray) -> np.ndarray:
        """Inverse of `_pinhole`: pinhole points back into the camera's image."""
        dist = self.renderer.sensor.distortion
        return distort_points(self.renderer.K, dist, pts) if dist else pts

    def default_inset(self, roi) -> int:
        """LoopConfig.roi_inset_px=None: GOAL_ROI_INSET_PX for a goal template, less where the box would fall
        under MIN_ROI (a target small in the image); 0 for a start template, whose box is thin at large rolls."""
        if self.template_from == "start" or self.oracle:  # the oracle's features need no inset
            return 0
        return int(min(GOAL_ROI_INSET_PX, max(0, (min(roi[2], roi[3]) - MIN_ROI) // 2)))

    def goal_image(self) -> tuple[np.ndarray, np.ndarray]:
        """(frame, target corners) of the goal image: the camera at the reference pose at time 0, the people
        left out (a user teaches the goal in a clear scene), through this run's camera model: the mean of
        `goal_frames` frames of it."""
        teacher = Renderer(self.scene, people=False)  # its own sensor state: the episode's frames are unchanged
        with self.scene.posed(self.scene.reference_configuration()):
            return teacher.still_average(self.goal_frames), teacher.ground_truth(occlusion=False).corners

    def _controller(self, desired_px: np.ndarray, goal: np.ndarray | None, roi):
        """The step-0 law on the desired corners (pinhole pixels): a built-in, or the outside law built at init."""
        cfg, K = self.config, self.renderer.K
        if self.law is not None or self.policy is not None:
            return self.law
        if cfg.controller == "dvs":
            from hvs_sim.control.dvs import DVSController

            return DVSController(K, goal, roi, self.desired_depth, self.ibvs_config)
        law = IBVSController if cfg.controller == "ibvs" else PBVSController
        return law(K, desired_px, self.desired_depth, self.ibvs_config, self.dofs)

    def _control_input(self, features_px, desired_px, true_depths, mode, motion, frame, goal, step) -> ControlInput:
        """What every law is given at a step (control/protocol.py); the features and s* in the pinhole image."""
        K = self.renderer.K
        reads_images = self.law is not None or self.image_law  # IBVS and PBVS read no image: no copy for them
        desired_px = self._pinhole(desired_px)
        if self.tracker is None and not self.oracle:  # a law on the images: no features (not the truth's)
            features_px = np.full_like(desired_px, np.nan)
        s = (features_px - K[:2, 2]) / np.diag(K)[:2]
        s_star = (desired_px - K[:2, 2]) / np.diag(K)[:2]
        depths = true_depths if true_depths is not None else scale_depths(s, s_star, self.desired_depth)
        return ControlInput(features=frozen(s), desired=frozen(s_star), depths=frozen(depths),
                            desired_depth=self.desired_depth, K=frozen(K), features_px=frozen(features_px),
                            desired_px=frozen(desired_px), mode=mode, camera_motion=frozen(motion),
                            dt=1.0 / self.scenario.fps, image=frozen(frame) if reads_images else None,
                            goal_image=frozen(goal) if reads_images else None, step=step)

    def _policy_input(self, frame, gt, goal, desired_px, step) -> PolicyInput:
        return PolicyInput(image=frozen(frame), joints=frozen(gt.joint_positions), goal_image=frozen(goal),
                           K=frozen(self.renderer.K), desired_px=frozen(self._pinhole(desired_px)),
                           dt=1.0 / self.scenario.fps, step=step)

    def _bounded(self, twist: np.ndarray, dofs: tuple[str, ...]) -> ControlOutput:
        """An outside law's or policy's twist in the DOFs it commands, under the loop's per-axis bounds (reported
        as saturated when they cut it, as for the built-in laws)."""
        cols = [DOF_NAMES.index(d) for d in dofs]
        out = np.zeros(6)
        out[cols] = np.asarray(twist, float)[cols]
        out, saturated = bound_twist(out, self.ibvs_config.max_linear, self.ibvs_config.max_angular)
        return ControlOutput(out, np.zeros(0), 0.0, 0.0, saturated, np.zeros(0), tuple(dofs))  # no gain of ours

    def __iter__(self) -> Iterator[StepRecord]:
        return self.run()

    def run(self) -> Iterator[StepRecord]:
        """The episode's steps. With `LoopConfig.pipeline` the tracker works on frame k in a second thread while
        this one steps the physics and renders frame k + 1: frame k's command then acts from step k + 1 (one frame
        of actuation latency, as a real camera's read-out and processing add), and the step takes about the longer
        of the two, not their sum."""
        if not self.config.pipeline:
            yield from self._sequential()
            return
        pool = ThreadPoolExecutor(1, thread_name_prefix="hvs_sim-track")
        threads = torch.get_num_threads()
        try:  # a core left to the renderer (torch's setting is process-wide, restored below)
            torch.set_num_threads(max(1, threads - 1))
            yield from self._pipelined(pool)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            torch.set_num_threads(threads)

    def _sequential(self) -> Iterator[StepRecord]:
        """Capture, track, control, physics one after another: a frame's command acts at once. wall_ms runs from the
        end of the step before, so what the consumer does with a record (the recording, the CSV) counts in the next."""
        wall = Stopwatch()
        cap = self._capture()
        ep = self._step_zero(cap)
        for step in range(self.config.steps):
            timings = dict(cap.timings)
            watch = Stopwatch()
            if ep.grow_from is not None:
                self._switch_to_near_goal(ep, step)
            truth = self.renderer.transfer(ep.flag0, cap.gt.corners, ep.roi0)  # where the features truly are
            first = self._start_tracker(ep, truth) if step == 0 else None
            seen = self._track_step(truth, cap.frame, first)
            timings["track"] = watch.ms()
            with lap(timings, "control"):
                seen, ctrl, cmd = self._control(ep, cap, seen, step)
                self._near_goal_due(ep, seen)
            timings["control"] += cap.depths_ms
            with lap(timings, "physics"):
                self.scene.advance(cmd.qdot)
            yield self._record(step, cap, ep, seen, ctrl, cmd, timings, wall_ms=wall.lap())
            if ep.aborted is not None:
                return
            if step + 1 < self.config.steps:
                cap = self._capture()

    def _pipelined(self, pool: ThreadPoolExecutor) -> Iterator[StepRecord]:
        """Frame k tracked in `pool` while this thread steps the physics with frame k − 1's command and captures frame
        k + 1. A step's render, ground_truth and physics (and the true depths in control) are therefore those of the
        next frame (0 after the last), its track the init's time here plus the tracker's own (Track.ms), and wall_ms
        runs from the end of the step before, so the consumer's time counts in the next step."""
        qdot_due = np.zeros(len(self.arm.limits.qdot_max))  # the command that acts this step: the step before's
        wall = Stopwatch()
        cap = self._capture()
        ep = self._step_zero(cap)
        for step in range(self.config.steps):
            watch = Stopwatch()
            if ep.grow_from is not None:  # no track is in flight between steps
                self._switch_to_near_goal(ep, step)
            truth = self.renderer.transfer(ep.flag0, cap.gt.corners, ep.roi0)
            first = self._start_tracker(ep, truth) if step == 0 else None
            pending = pool.submit(self._track, cap.frame, first) if self.tracker is not None else None
            init_ms = watch.ms()
            timings = {"render": 0.0, "ground_truth": 0.0, "physics": 0.0}  # the last step captures no next frame
            nxt, depths_ms = None, 0.0
            if step + 1 < self.config.steps:  # meanwhile: physics with the command due, then the next frame
                with lap(timings, "physics"):
                    self.scene.advance(qdot_due)
                nxt = self._capture()
                timings.update(nxt.timings)
                depths_ms = nxt.depths_ms
            seen = self._track_step(truth, pending=pending)
            timings["track"] = init_ms + (seen.track.ms if seen.track is not None else 0.0)
            with lap(timings, "control"):
                seen, ctrl, cmd = self._control(ep, cap, seen, step)  # at the next step's arm configuration
                self._near_goal_due(ep, seen)
            timings["control"] += depths_ms
            yield self._record(step, cap, ep, seen, ctrl, cmd, timings, wall_ms=wall.lap())
            if ep.aborted is not None:
                return
            qdot_due, cap = cmd.qdot, nxt

    def _capture(self) -> Capture:
        """Everything a step reads from the scene at its state: the frame and the truth that grades it."""
        r, scene, timings = self.renderer, self.scene, {}
        with lap(timings, "render"):
            frame = r.rgb() if self.renders_frames else None
        with lap(timings, "ground_truth"):
            gt = r.ground_truth(occlusion=self.config.evaluate, counts=False)
        watch = Stopwatch()
        depths = self.true_depths() if self.ibvs_config.depth == "true" else None  # only when asked
        depths_ms = watch.ms()
        return Capture(frame, gt, scene.time, scene.pose_error(), scene.people_poses(), scene.arm_poses(), depths,
                       timings, depths_ms)

    def _step_zero(self, cap: Capture) -> Episode:
        """What the episode keeps from its first frame: the template's image and box, s*, the law, the policy's reset
        and the feature filter (the tracker starts in _start_tracker, whose time counts as tracking)."""
        r, res = self.renderer, self.resolved
        # the template's image and the target's corners in it: this first frame, or the goal image
        template_frame, flag0 = (cap.frame, cap.gt.corners) if res.template_from == "start" else self.goal_image()
        goal = None if res.template_from == "start" else template_frame
        outline = roi_from_corners(flag0)
        inset = self.default_inset(outline) if res.roi_inset_px is None else res.roi_inset_px
        roi = self._template_box(outline, inset, "roi_inset_px")
        roi0 = roi_corners(roi)
        desired = r.transfer(flag0, self.flag_desired, roi0)
        controller = self._controller(self._pinhole(desired), goal, roi)
        near_goal, growth = None, res.near_goal
        if growth == NEAR_GOAL_AUTO:
            growth, self.near_goal_off = near_goal_growth(outline, self.scenario.camera)
        self.near_goal_growth = growth
        if growth is not None:  # the grown box checked now: a run that cannot switch says so
            grown = self._template_box(outline, growth, "near_goal_inset_px")
            near_goal = Template(grown, roi_corners(grown), growth,
                                 r.transfer(flag0, self.flag_desired, roi_corners(grown)))
        if self.policy is not None:
            try:
                self.policy.reset(self._policy_input(cap.frame, cap.gt, goal, desired, 0))
            except Exception as exc:  # outside code: the run cannot start, and says why
                raise StateError(f"policy {self.config.policy!r} failed in reset(): {type(exc).__name__}: {exc}") \
                    from exc
        feature_filter = self._feature_filter(desired) if res.filter_alpha > 0 else None
        ep = Episode(flag0, roi, roi0, inset, desired, template_frame, goal, controller, feature_filter, near_goal)
        self._start_safety(ep, cap)
        return ep

    def _start_safety(self, ep: Episode, cap: Capture) -> None:
        """The safety rule's state for the episode: the gate on s*, the envelope from the camera's start pose (forward
        kinematics) and the taught goal, and the carrier that predicts each measurement from the camera's motion."""
        cam, safety = self.scenario.camera, self.config.safety
        ep.gate = SafetyGate(safety, self.scenario.fps, ep.desired, cam.width, cam.height)
        goal_pos, goal_R = self.scene.reference_pose()
        ep.envelope = Envelope(safety, cap.gt.camera.t, cap.gt.camera.R, goal_pos, goal_R)
        ep.carrier = FeatureFilter(self.renderer.K, 1.0, self._pinhole(ep.desired), self.desired_depth) \
            if self.tracker is not None else None

    def _template_box(self, outline, inset: int, option: str) -> tuple[int, int, int, int]:
        """The template's box: the target's outline box inset (grown, when negative); InputError when a grown box runs
        off the goal image."""
        roi = inset_roi(outline, inset)
        cam = self.scenario.camera  # the goal image's size (a run may render no frames)
        if inset < 0 and not box_in_view(roi, cam):
            raise InputError(f"the template grown {-inset} px beyond the target's outline, {roi[2]}×{roi[3]} px at "
                             f"({roi[0]}, {roi[1]}), runs off the {cam.width}×{cam.height} goal image: grow it less (a "
                             f"{option} nearer 0)")
        return roi

    def _near_goal_due(self, ep: Episode, seen: Measured) -> None:
        """After a step's control: when the features (as control used them) are within near_goal_px of s* and the
        grown box, carried by their homography, is in view, the switch to the grown template is due at the next
        step (ep.grow_from: that homography, the tracker's seed)."""
        if (ep.near_goal is None or ep.grown_at is not None or seen.fault is not None or seen.mode != "align"
                or ep.gate.closed_because is not None):
            return
        if float(np.linalg.norm(seen.features - ep.desired, axis=1).mean()) > self.config.near_goal_within_px:
            return
        A = perspective_transform(ep.roi0, seen.features)  # frame from goal image
        grown = apply_warp(A, ep.near_goal.corners)
        if corners_in_view(grown, self.scenario.camera, IN_VIEW_MARGIN_PX):
            ep.grow_from = A

    def _switch_to_near_goal(self, ep: Episode, step: int) -> None:
        """The tracker (or the near-goal one, near_goal_scale) initialised on the grown template and seeded where the
        small one's corners put it; s*, the law and the feature filter start again on the grown box's corners."""
        near, A = ep.near_goal, ep.grow_from
        tracker = self.near_goal_tracker or self.tracker
        try:
            tracker.init(ep.template_frame, near.roi)
            tracker.seed(A)
        except Exception as exc:  # any cause: the tracker has no template left to servo on
            raise StateError(f"tracker {self.tracker_name!r} could not switch to the near-goal template (ROI "
                             f"{near.roi}) at step {step}: {exc}") from exc
        self.tracker = tracker
        ep.roi, ep.roi0, ep.inset, ep.desired = near.roi, near.corners, near.inset, near.desired
        ep.controller = self._controller(self._pinhole(near.desired), ep.goal, near.roi)
        if ep.feature_filter is not None:
            ep.feature_filter = self._feature_filter(near.desired)
        ep.gate.set_desired(near.desired)
        if ep.carrier is not None:  # other corners from here: nothing to carry
            ep.carrier = FeatureFilter(self.renderer.K, 1.0, self._pinhole(near.desired), self.desired_depth)
        ep.grown_at, ep.grow_from = step, None

    def _feature_filter(self, desired: np.ndarray) -> FeatureFilter:
        """A fresh feature filter (LoopConfig.feature_filter, resolved) on s* = `desired`."""
        return FeatureFilter(self.renderer.K, self.resolved.filter_alpha, self._pinhole(desired), self.desired_depth)

    def _start_tracker(self, ep: Episode, truth: np.ndarray) -> Track | None:
        """The tracker's init on the template: its own track of the first frame with a start template; with a goal
        one it is then seeded at the target's corners in the first frame. Without a template there is nothing to
        servo on: a failure ends the run."""
        if self.tracker is None:
            return None
        try:
            first = self.tracker.init(ep.template_frame, ep.roi)
            if self.template_from == "goal":  # the target's corners marked in the first frame
                first = None
                self.tracker.seed(perspective_transform(ep.roi0, truth))
            return first
        except Exception as exc:  # any cause: the run cannot go on, and says why
            where = "the first frame" if self.template_from == "start" else "the goal image and the first frame"
            raise StateError(f"tracker {self.tracker_name!r} could not start on {where} (template ROI {ep.roi}): "
                             f"{exc}") from exc

    def _track(self, frame: np.ndarray, first: Track | None) -> Track:
        """The tracker's corners for a frame (`first`: the init's own track of step 0, when it has one)."""
        track = first if first is not None else self.tracker.update(frame)
        if not np.all(np.isfinite(track.corners)):
            raise FloatingPointError("tracker returned non-finite corners")
        return track

    def _track_step(self, truth: np.ndarray, frame: np.ndarray | None = None, first: Track | None = None,
                    pending: Future | None = None) -> Measured:
        """The step's corners: the tracker's, here or from the tracking thread (`pending`), else the truth's. A
        tracker fault must not crash the run: it is recorded, and control holds the arm."""
        try:
            if self.tracker is None:  # the oracle's features; a law on the images or a policy reads none
                return Measured(None, truth, truth, truth, "align", None)
            track = pending.result() if pending is not None else self._track(frame, first)
            return Measured(track, truth, track.corners, track.corners, track.mode, None)
        except Exception as exc:  # noqa: BLE001 - any tracker fault
            lost = truth * np.nan
            return Measured(None, truth, lost, lost, "fault", f"{type(exc).__name__}: {exc}")

    def _control(self, ep: Episode, cap: Capture, seen: Measured,
                 step: int) -> tuple[Measured, ControlOutput | None, JointCommand]:
        """The law's (or policy's) twist on the step's features, through the feature filter, as joint velocities at
        the arm's configuration now. A fault (the tracker's, or the law's) gives a zero twist: the arm holds."""
        features, mode, fault = seen.features, seen.mode, seen.fault
        ctrl = None
        control_px = self._pinhole(features) if fault is None else features
        camera, prev = cap.gt.camera, ep.camera_prev
        motion = np.eye(4) if prev is None else np.linalg.solve(prev.matrix(), camera.matrix())
        ep.camera_prev = camera
        if ep.feature_filter is not None:  # the camera's pose from the joints' forward kinematics, as ArmDriver reads it
            control_px = ep.feature_filter.update(control_px, camera, usable=fault is None and mode != "lost")
            if fault is None:
                features = self._distort(control_px)
        if fault is None:
            # PBVS cannot take a pose from a degenerate quad, an outside law or policy may fail or answer garbage:
            # like a tracker fault, stop the arm and record it
            try:
                if self.policy is not None:
                    ctrl = self._bounded(self.policy.act(self._policy_input(cap.frame, cap.gt, ep.goal, ep.desired,
                                                                            step)), self.dofs)
                else:
                    inp = self._control_input(control_px, ep.desired, cap.depths, mode, motion, cap.frame, ep.goal, step)
                    ctrl = ep.controller.compute(inp)
                    if self.law is not None:  # (twist, dofs): bounded as the built-in laws bound theirs
                        ctrl = self._bounded(ctrl[0], ctrl[1] or self.dofs)
            except self._law_errors as exc:
                fault, mode = f"{type(exc).__name__}: {exc}", "fault"
                if ep.feature_filter is not None:  # a faulty frame clears the filter, as a tracker fault does
                    ep.feature_filter.reset()
        twist = self._safe_twist(ep, cap, seen, ctrl, fault)
        if ctrl is not None:
            ctrl = dataclasses.replace(ctrl, twist=twist)
        cmd = self.arm.command(twist)
        return dataclasses.replace(seen, features=features, mode=mode, fault=fault), ctrl, cmd

    def _safe_twist(self, ep: Episode, cap: Capture, seen: Measured, ctrl: ControlOutput | None,
                    fault: str | None) -> np.ndarray:
        """The law's twist through the safety rule (control/safety.py): the gate judges the tracker's own corners
        (not the filtered ones) and holds the arm while it does not see; a twist that would carry the camera out of
        the envelope within one step is not commanded, and the episode ends (ep.aborted)."""
        jump, px = None, None
        if self.tracker is not None and seen.fault is None:
            px = seen.tracked
            pinhole = self._pinhole(px)
            carried = ep.carrier.predict(cap.gt.camera) if ep.carrier.state is not None else None
            jump = None if carried is None else float(np.linalg.norm(pinhole - carried, axis=1).max())
            ep.carrier.update(pinhole, cap.gt.camera, usable=seen.mode != "lost")
        confidence = seen.track.confidence if seen.track is not None else None
        ep.held_because = ep.gate.update(px, seen.mode, confidence, fault is not None, jump)
        twist = ep.gate.twist(ctrl.twist if ctrl is not None else None)
        if not np.any(twist):
            return twist
        inside = ep.envelope.check(cap.gt.camera.t, cap.gt.camera.R, twist, 1.0 / self.scenario.fps)
        if not inside.inside:
            ep.aborted = inside.reason
            return np.zeros(6)
        return twist

    def _record(self, step: int, cap: Capture, ep: Episode, seen: Measured, ctrl: ControlOutput | None,
                cmd: JointCommand, timings: dict[str, float], wall_ms: float | None = None) -> StepRecord:
        """The step as logged and graded: what the loop did, beside the truth it did not see."""
        gt, truth, res = cap.gt, seen.truth, self.resolved
        twist, gain, sat, sv = ((ctrl.twist, ctrl.gain, ctrl.saturated, ctrl.singular_values) if ctrl is not None
                                else (np.zeros(6), 0.0, False, np.zeros(0)))
        graded = seen.fault is None and (self.tracker is not None or self.oracle)
        return StepRecord(
            step=step, time=cap.time, frame=cap.frame if self.config.keep_frames else None, track=seen.track,
            mode=seen.mode, features=seen.features, gt_features=truth, desired=ep.desired,
            error_px=float(np.linalg.norm(truth - ep.desired, axis=1).mean()),
            tracker_error_px=float(np.linalg.norm(seen.tracked - truth, axis=1).mean()) if graded else float("nan"),
            occlusion=gt.occlusion, twist=twist, qdot=cmd.qdot, q=gt.joint_positions, camera=gt.camera, gain=gain,
            saturated=sat or cmd.velocity_saturated, limit_blocked=cmd.limit_blocked, fault=seen.fault,
            timings=timings, pose_error=cap.pose_error, singular_values=sv,
            dofs=(ctrl.dofs or res.dofs) if ctrl is not None else res.dofs, damping=self.ibvs_config.damping,
            feature_filter=res.filter_alpha,
            filter_restarted=ep.feature_filter is not None and ep.feature_filter.restarted,
            template=(res.template_from, int(ep.inset), res.goal_frames),
            target_in_view=corners_in_view(gt.corners, self.scenario.camera),
            controlled_pose_error=self.controlled_pose_error(cap.pose_error), people=cap.people, arm=cap.arm,
            wall_ms=wall_ms, held_because=ep.held_because, aborted=ep.aborted)
