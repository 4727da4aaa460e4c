"""The run's plan: the rules between tracker, law and settings, and LoopConfig's "None: decided by the loop"
settings resolved once (ResolvedLoop) from the tracker's and the law's capabilities."""

from __future__ import annotations

from dataclasses import dataclass

from hvs_sim import plugins
from hvs_sim.control.feature_filter import FEATURE_FILTER_ALPHA
from hvs_sim.control.laws.ibvs import CONTROLLERS, TRACKED_6DOF_DAMPING, dofs_for
from hvs_sim.errors import ConfigError
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.laws import ServoLaw, law_caps
from hvs_sim.servo.parts import GOAL_FRAMES, NEAR_GOAL_AUTO, NEAR_GOAL_SCALE, ResolvedLoop
from hvs_sim.tracking import TRACKER_NAMES, Tracker, make_tracker


def check_combination(tracker: str, config: LoopConfig, image_law: bool | None = None) -> None:
    """The rules between the tracker's name and the loop's settings (ServoLoop applies them, and a sweep checks its
    whole grid with them before it runs). `image_law`: whether the law reads only the images; None: what the settings
    say without building the law (dvs does; an outside law is given the benefit of the doubt)."""
    caps = law_caps(config.controller)  # None: an outside law not built, which either rule may hold for
    unknown = image_law is None and caps is None
    if image_law is None:
        image_law = caps is not None and not caps.features
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


def resolve(name: str, config: LoopConfig, tracker: Tracker | plugins.ExternalTracker | None, law,
            policy) -> ResolvedLoop:
    """LoopConfig's None settings decided once, from the tracker (`name`, and the object: None for the oracle and for
    no tracker), the outside law or policy (None: a built-in law) and the DOFs the features observe."""
    oracle = name == plugins.GROUND_TRUTH
    # the DOFs the features observe: ground truth and a homography tracker give perspective corners
    warp = "homography" if tracker is None else tracker.warp
    declared = (policy.dofs if policy is not None else law.dofs if law is not None else None)
    dofs = tuple(config.ibvs.dofs or declared or dofs_for(warp))
    tracked_6dof = tracker is not None and len(dofs) == 6
    damping = config.ibvs.damping
    if damping is None:  # exact features need none; tracked ones on six DOF do (IBVSConfig.damping)
        caps = law_caps(config.controller, law)
        damping = TRACKED_6DOF_DAMPING if tracked_6dof and caps is not None and caps.damped else 0.0
    alpha = config.feature_filter
    alpha = (FEATURE_FILTER_ALPHA if tracked_6dof else 0.0) if alpha is None else float(alpha)
    can_seed = tracker is None or tracker.can_seed  # an outside tracker without seed(A): its first frame
    template_from = template_view(config.template_from, tracked_6dof and can_seed)
    if tracker is None and not oracle:  # a law on the images or a policy: they compare with the goal
        if config.template_from == "start":
            raise ConfigError("a photometric law or a policy compares the frames with the goal image: leave "
                              "template_from out (or give 'goal')")
        template_from = "goal"
    if template_from == "goal" and not can_seed:
        raise ConfigError(f"tracker {name!r} has no seed(A), so it cannot take its template from the goal image "
                          "and be placed on the first frame: use template_from='start'")
    if template_from == "start" and config.goal_frames is not None:
        raise ConfigError(f"goal_frames ({config.goal_frames}) averages frames into a goal image, but this run's "
                          "template comes from its first frame (template_from='start'): leave goal_frames out, or "
                          "use template_from='goal'")
    if template_from == "start":
        goal_frames = None
    elif oracle:  # the oracle takes only the target's corners from a goal image: one frame
        goal_frames = 1
    else:
        goal_frames = config.goal_frames or GOAL_FRAMES
    inset = config.roi_inset_px  # default_inset's answer, where it needs no goal image
    if inset is None and (template_from == "start" or oracle):
        inset = 0
    if inset is not None and inset < 0 and template_from == "start":
        raise ConfigError(f"roi_inset_px {inset} grows the template into the target's surroundings, which only a "
                          "goal template may take in: this run's template comes from its first frame (give "
                          "template_from='goal', or an inset ≥ 0)")
    if config.ibvs.depth == "true" and inset is not None and inset < 0:
        raise ConfigError("depth='true' gives IBVS the depths of the target's own corners; a grown template's "
                          "corners lie beyond them, in its plane: leave depth at 'scale' (the tracked scale)")
    near_goal, near_off, near_scale = _resolve_near_goal(name, config, tracker, template_from, inset)
    return ResolvedLoop(warp, dofs, damping, alpha, template_from, goal_frames, inset, near_goal, near_off,
                        near_scale)

def _resolve_near_goal(name: str, config: LoopConfig, tracker: Tracker | plugins.ExternalTracker | None,
                       template_from: str,
                       inset: int | None) -> tuple[int | str | None, str | None, float | None]:
    """(the near-goal template's growth: a number, NEAR_GOAL_AUTO for step 0 to decide, or None; why there is
    none where NEAR_GOAL_AUTO cannot apply; the working scale a second tracker is built at, None: the loop's
    own). A number the run cannot apply is refused."""
    near = config.near_goal_inset_px
    if near is None:
        return None, None, None
    why = None
    if tracker is None:
        why = f"tracker {name!r} has no template"
    elif template_from != "goal":
        why = "this run's template comes from its first frame"
    elif config.ibvs.depth == "true":
        why = ("depth='true' gives IBVS the depths of the target's own corners, and a grown template's corners lie "
               "beyond them")
    elif inset is not None and inset < 0:
        why = f"roi_inset_px ({inset}) grows the first template already"
    elif near == NEAR_GOAL_AUTO and not tracker.near_goal:
        why = (f"{name!r} declines the near-goal template (its `near_goal` is False; give near_goal_inset_px "
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
    # a tracker with a working scale is built again at the near-goal one (Tracker.with_scale); any other is its own
    own = None if tracker is None else tracker.working_scale
    if own is None:
        if scale is not None:
            raise ConfigError(f"near_goal_scale builds a built-in tracker again at another working scale; "
                              f"{name!r} is not one with a working scale (those of "
                              f"{', '.join(TRACKER_NAMES)} that take `scale`): leave near_goal_scale out")
        return near, None, None
    scale = NEAR_GOAL_SCALE if scale is None else float(scale)
    return near, None, (None if abs(own - scale) < 1e-12 else scale)


@dataclass(frozen=True)
class Method:
    """A servo method's parts as a loop drives them, and its plan: what a ServoLoop builds before its scene, and what
    the servo benchmark asks of a method (`goal_template`, `takes_near_goal_scale`) instead of re-deriving the loop's
    rules from its name."""

    tracker: Tracker | plugins.ExternalTracker | None  # None: the oracle, or no tracker (a law on the images, a policy)
    law: plugins.ExternalController | None  # the outside law, built (None: a built-in)
    policy: plugins.ExternalPolicy | None  # the outside policy, built (None: none)
    servo_law: ServoLaw
    resolved: ResolvedLoop

    @property
    def goal_template(self) -> bool:
        """Whether its episodes track a template cut from the goal image."""
        return self.tracker is not None and self.resolved.template_from == "goal"

    @property
    def takes_near_goal_scale(self) -> bool:
        """Whether LoopConfig.near_goal_scale applies to it: a goal template, and a tracker with a working scale."""
        return self.goal_template and self.tracker is not None and self.tracker.working_scale is not None


def build_method(tracker: str, config: LoopConfig, tracker_settings: dict | None = None) -> Method:
    """The method's law or policy (outside ones built before the tracker, and the two checked against the tracker's
    name), its tracker and the plan; ConfigError where the combination cannot run. No scene is built."""
    law = None if config.controller in CONTROLLERS else plugins.build("controller", config.controller)
    policy = None if config.policy is None else plugins.build("policy", config.policy)
    servo_law = ServoLaw(config.controller, law)  # what the law uses, and the law on each template
    check_combination(tracker, config, not servo_law.caps.features)
    built = loop_tracker(tracker, tracker_settings or {})
    return Method(built, law, policy, servo_law, resolve(tracker, config, built, law, policy))
