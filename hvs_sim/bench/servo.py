"""`hvs-sim bench servo`: closed-loop convergence under occlusion from random 6-DOF start poses.

A method is a loop tracker with, optionally, its warp model and the servo law, `TRACKER[:WARP][/CONTROLLER]`, e.g.
`ground_truth`, `ground_truth/pbvs`, `hybrid:homography`, `hybrid` (the similarity hybrid, which controls 4 DOF),
`none/dvs` (photometric servoing, no tracker), or a policy in place of both, `policy=NAME`. TRACKER, CONTROLLER and
NAME are built-in names, registered or entry-point names, or outside references written in braces so that their
colon is not read as the warp's: `{mypkg.track:make}/{mypkg.law:make}`, `policy={path/net.py:make}`
(hvs_sim.plugins; an outside tracker declares its own warp). Start poses are drawn over the ranges of the classic
IBVS test cases (ViSP's tutorials, Chaumette's examples), scaled to the 0.8 m standoff: lateral
±10 cm, target depth 0.7–1.4 × the standoff, roll ±60°, pitch and yaw ±15°; a draw the arm cannot reach or
from which the target is not fully in view is drawn again (seeded)."""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hvs_sim.bench.pool import collect_jobs, config_json, episode_threads
from hvs_sim.bench.suites import TILT_MAX_DEG
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.outputs import write_atomic
from hvs_sim.provenance import code_provenance
from hvs_sim.sensor import REALISTIC_PRESET
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.parts import NEAR_GOAL_AUTO
from hvs_sim.validate import check_number

SERVO_METHODS = ("ground_truth", "ground_truth/pbvs", "hybrid:homography", "hybrid:homography/pbvs", "hybrid")
RESULTS_SCHEMA = "hvs_sim.servo-results/2"  # docs/results-schema.md
# start offsets (camera frame): dx, dy (m), the target's depth as a share of the standoff, roll, pitch, yaw (rad).
# Results before stop 30 (archive/servo_6dof_v4 and older) were drawn over a depth of 0.6-1.3 (a sign slip, found in
# review)
LATERAL_M, DEPTH_RANGE = 0.10, (0.7, 1.4)
ROLL_MAX, TILT_MAX = np.radians(60.0), np.radians(TILT_MAX_DEG)
MAX_DRAWS = 50  # start poses drawn per episode before giving up (unreachable or target out of view)


EXTRA_STEPS = 60  # an episode runs this long past the scenario's end, to see the recovery
SUCCESS_PX = 1.0  # success = converged and final ground-truth error ≤ this


@dataclass(frozen=True)
class ServoBenchConfig:
    trackers: tuple[str, ...] = SERVO_METHODS  # methods: TRACKER[:homography][/pbvs] (module docstring)
    scenarios: tuple[str, ...] = ("clear", "walk_by", "pause")
    episodes: int = 20
    seed0: int = 200
    extra_steps: int = EXTRA_STEPS
    steps: int | None = None  # overrides scenario length + extra_steps (smoke runs)
    success_px: float = SUCCESS_PX
    workers: int = 1
    camera: str = REALISTIC_PRESET  # camera model of every episode (hvs_sim.camera_model.SENSOR_PRESETS)
    people: str = "textured"  # how the people look ("plain": the flat figures of the earlier benchmarks)
    arm: str = "jaco"  # the arm the camera rides on (hvs_sim.scene.arms.ARMS)
    seeds: tuple[int, ...] | None = None  # explicit episode seeds (then `episodes` and `seed0` are not used)
    damping: float | None = None  # IBVSConfig.damping of every episode (None: the loop's default)
    template_from: str | None = None  # LoopConfig.template_from of every episode (None: the loop's default)
    roi_inset_px: int | None = None  # LoopConfig.roi_inset_px of every episode (None: the loop's default)
    # LoopConfig.near_goal_inset_px of every episode (NEAR_GOAL_AUTO: the loop's default; None or "off": one template)
    near_goal_inset_px: int | str | None = NEAR_GOAL_AUTO
    near_goal_scale: float | None = None  # LoopConfig.near_goal_scale of every episode
    goal_frames: int | None = None  # LoopConfig.goal_frames of the episodes with a goal template (None: the loop's default)
    feature_filter: float | None = None  # LoopConfig.feature_filter of the episodes with tracked corners (None: default)
    width: int = 640  # image size of every episode
    height: int = 480
    tilt_deg: float = TILT_MAX_DEG  # start poses' pitch and yaw bound (0: the 4-DOF distribution)
    suite: str | None = None  # the versioned suite these settings are (bench/suites.py), recorded with the results
    safety: bool = True  # LoopConfig.safety enabled (False: the loop without the safety rule, an ablation)

    def __post_init__(self):
        from hvs_sim import plugins
        from hvs_sim.scene.scenarios import PEOPLE_STYLES, SCENARIO_NAMES
        from hvs_sim.sensor import sensor_preset
        from hvs_sim.tracking import TRACKER_NAMES, check_tracker

        if not self.trackers:
            raise ConfigError("the servo benchmark needs at least one method")
        from hvs_sim.scene.arms import ARM_NAMES

        for what, values, accepted in (("scenario", self.scenarios, SCENARIO_NAMES),
                                       ("people style", (self.people,), PEOPLE_STYLES), ("arm", (self.arm,), ARM_NAMES)):
            if not values:
                raise ConfigError(f"the servo benchmark needs at least one {what}; accepted: {', '.join(accepted)}")
            for v in values:
                if v not in accepted:
                    raise choice_error(what, v, accepted)
        from hvs_sim.servo.plan import check_combination

        for m in self.trackers:  # what a worker would refuse is refused here, before any episode runs
            tracker, warp, controller, policy = parse_method(m)
            try:
                plugins.check("tracker", tracker)  # LoopConfig checks the law and the policy
                check_combination(tracker, LoopConfig(controller=controller, policy=policy))
                for kind, name in (("tracker", tracker), ("controller", controller), ("policy", policy)):
                    plugins.probe(kind, name)  # built once here: a broken factory is found before any episode
            except ConfigError as exc:
                raise ConfigError(f"servo method {m!r}: {exc}") from None
            if warp and tracker not in TRACKER_NAMES:
                raise ConfigError(f"servo method {m!r}: an outside tracker declares its warp itself (its `warp` "
                                  f"attribute); leave :{warp} out")
            if warp:  # e.g. a residual tracker with a homography
                try:
                    check_tracker(tracker, warp=warp)
                except ConfigError as exc:
                    raise ConfigError(f"servo method {m!r}: {exc}") from None
        check_number("episodes", self.episodes, 1, integer=True)
        check_number("seed0", self.seed0, 0, integer=True)
        check_number("extra_steps", self.extra_steps, 0, integer=True)
        if self.steps is not None:
            check_number("steps", self.steps, 1, integer=True)
        check_number("success_px", self.success_px, 0, lo_open=True)
        check_number("workers", self.workers, 1, integer=True)
        if self.seeds is not None:
            if not self.seeds:
                raise ConfigError("seeds, when given, must list at least one episode seed")
            for s in self.seeds:
                check_number("seed", s, 0, integer=True)
        sensor_preset(self.camera)
        check_number("width", self.width, 64, 4096, integer=True)
        check_number("height", self.height, 64, 4096, integer=True)
        check_number("tilt_deg", self.tilt_deg, 0, TILT_MAX_DEG)
        if self.damping is not None:
            check_number("damping", self.damping, 0, 1)
        loop = LoopConfig(template_from=self.template_from, roi_inset_px=self.roi_inset_px, goal_frames=self.goal_frames,
                          feature_filter=self.feature_filter, near_goal_inset_px=self.near_goal_inset_px,
                          near_goal_scale=self.near_goal_scale)  # checks them
        object.__setattr__(self, "near_goal_inset_px", loop.near_goal_inset_px)  # "off" as None
        if self.goal_frames is not None and self.template_from == "start":
            raise ConfigError(f"goal_frames ({self.goal_frames}) averages frames into a goal image; with template_from "
                              "'start' no episode has one: leave one of them out")
        explicit = self.near_goal_inset_px not in (None, NEAR_GOAL_AUTO)  # auto applies where it can, by itself
        grown = [flag for flag, on in (("--near-goal-inset", explicit),
                                       ("a negative --roi-inset", (self.roi_inset_px or 0) < 0)) if on]
        plans = self.method_plans() if self.near_goal_scale is not None or grown else {}  # asked once, if at all
        if self.near_goal_scale is not None and not any(p.takes_near_goal_scale for p in plans.values()):
            raise ConfigError(f"--near-goal-scale ({self.near_goal_scale}) is the working scale of a built-in tracker on "
                              "the near-goal template, and no method here has one (a goal template and a tracker with "
                              "a working scale, e.g. hybrid:homography): leave it out")
        if grown:  # a grown template needs a tracked goal template: refused before any episode, not in the middle
            for m in self.trackers:
                if not plans[m].goal_template:
                    raise ConfigError(f"servo method {m!r} has no goal template to grow ({grown[0]} applies to a "
                                      "tracker on six DOF, e.g. hybrid:homography): run it without that option")

    def method_plans(self) -> dict[str, MethodPlan]:
        """Each method's plan (method_plan; its tracker and outside parts are built for it)."""
        return {m: method_plan(m, self.template_from, self.damping) for m in self.trackers}

    @property
    def episode_seeds(self) -> list[int]:
        return list(self.seeds) if self.seeds is not None else [self.seed0 + i for i in range(self.episodes)]


def _median_or_none(values) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.median(vals)) if vals else None


def _max_or_none(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.max(values)) if values else None


def _split_top(text: str, sep: str) -> tuple[str, str]:
    """`text` split at the first `sep` outside braces ("{mod:make}:homography" at ":" → "{mod:make}", "homography")."""
    depth = 0
    for i, c in enumerate(text):
        depth += (c == "{") - (c == "}")
        if c == sep and depth == 0:
            return text[:i], text[i + 1:]
    return text, ""


def _unbrace(text: str) -> str:
    return text[1:-1] if text.startswith("{") and text.endswith("}") else text


def parse_method(method: str) -> tuple[str, str | None, str, str | None]:
    """`TRACKER[:WARP][/CONTROLLER]` or `policy=NAME` → (tracker, warp or None, controller, policy or None); the
    names are checked where they are used (plugins.check)."""
    from hvs_sim.plugins import NO_TRACKER
    from hvs_sim.tracking.warp import WARPS

    if not isinstance(method, str) or not method or method.count("{") != method.count("}"):
        raise ConfigError(f"servo method {method!r} invalid; accepted: TRACKER[:WARP][/CONTROLLER] or policy=NAME")
    if method.startswith("policy="):
        policy = _unbrace(method[len("policy="):])
        if not policy:
            raise ConfigError("servo method 'policy=' names no policy; e.g. policy={mypkg.net:make}")
        return NO_TRACKER, None, "ibvs", policy
    rest, controller = _split_top(method, "/")
    tracker, warp = _split_top(rest, ":")
    tracker, controller = _unbrace(tracker), _unbrace(controller) or "ibvs"
    if not tracker or (warp and warp not in WARPS) or (warp and tracker in ("ground_truth", NO_TRACKER)) \
            or (":" in tracker and not rest.startswith("{")):
        raise ConfigError(f"servo method {method!r} invalid; accepted: TRACKER[:WARP][/CONTROLLER] with WARP one of "
                          f"{', '.join(WARPS)} (not for ground_truth or none) and CONTROLLER ibvs, pbvs, dvs or a "
                          "plugin, e.g. hybrid:homography/pbvs, none/dvs, {mypkg.track:make}/{mypkg.law:make}; or "
                          "policy=NAME")
    return tracker, warp or None, controller, None


def portable_method(method: str) -> str:
    """The method spelled so that a worker process resolves every part of it to the same factory (plugins.portable)."""
    from hvs_sim import plugins

    tracker, warp, controller, policy = parse_method(method)
    if policy is not None:
        return "policy={" + plugins.portable("policy", policy) + "}"
    t = plugins.portable("tracker", tracker)
    c = plugins.portable("controller", controller)
    brace = (lambda x: "{" + x + "}" if ":" in x else x)
    return brace(t) + (f":{warp}" if warp else "") + "/" + brace(c)


def offset_range(standoff: float, tilt: float = TILT_MAX) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of (dx, dy, dz, roll, pitch, yaw); dz > 0 moves the camera towards the target; `tilt` (rad) bounds
    pitch and yaw (0: the 4-DOF distribution)."""
    lo = np.array([-LATERAL_M, -LATERAL_M, (1 - DEPTH_RANGE[1]) * standoff, -ROLL_MAX, -tilt, -tilt])
    hi = np.array([LATERAL_M, LATERAL_M, (1 - DEPTH_RANGE[0]) * standoff, ROLL_MAX, tilt, tilt])
    return lo, hi


def episode_offset(seed: int, standoff: float = 0.8, draw: int = 0, tilt: float = TILT_MAX) -> tuple[float, ...]:
    """The `draw`-th candidate start offset of episode `seed` (dx, dy, dz m; roll, pitch, yaw rad)."""
    rng = np.random.default_rng([seed, 11, draw])
    return tuple(float(v) + 0.0 for v in rng.uniform(*offset_range(standoff, tilt)))


@dataclass(frozen=True)
class MethodPlan:
    """What the benchmark asks of a method's loop (servo/plan.py: Method) to set its episodes' options."""

    goal_template: bool  # its episodes track a template cut from the goal image (goal_frames apply)
    takes_near_goal_scale: bool  # a goal template and a tracker with a working scale (near_goal_scale applies)


def method_plan(method: str, template_from: str | None, damping: float | None = None) -> MethodPlan:
    """The method's plan as its episodes' loop resolves it (servo/plan.py: build_method builds its tracker and an
    outside law or policy, no scene; the built parts are let go)."""
    from hvs_sim import plugins
    from hvs_sim.control.laws.ibvs import IBVSConfig
    from hvs_sim.servo.plan import build_method

    tracker, warp, controller, policy = parse_method(method)
    tracked = tracker not in (plugins.GROUND_TRUTH, plugins.NO_TRACKER)
    try:
        config = LoopConfig(controller=controller, policy=policy, ibvs=IBVSConfig(damping=damping),
                            template_from=template_from if tracked else None, near_goal_inset_px=None)
        built = build_method(tracker, config, {"warp": warp} if warp else None)
    except ConfigError as exc:
        raise ConfigError(f"servo method {method!r}: {exc}") from None
    return MethodPlan(built.goal_template, built.takes_near_goal_scale)


def episode_scenario(scen_name: str, seed: int, tilt: float = TILT_MAX, **overrides):
    """The episode's scenario with the first drawn start pose that the arm reaches and from which
    the target is fully in view (the same for every method of that seed)."""
    return episode_start(scen_name, seed, tilt, **overrides)[0]


def episode_start(scen_name: str, seed: int, tilt: float = TILT_MAX, **overrides):
    """(episode_scenario, the draws it took): draws before the last are start poses the arm could not reach or
    from which the target was not in view, which the benchmark counts per arm."""
    from hvs_sim.scene.scenarios import make_scenario
    from hvs_sim.servo.teach import check_start_pose

    last = None
    base = make_scenario(scen_name, mount="arm", seed=seed, **overrides)
    for draw in range(MAX_DRAWS):
        scen = dataclasses.replace(base, start_offset=episode_offset(seed, base.standoff, draw, tilt))
        try:
            check_start_pose(scen)
            return scen, draw + 1
        except ConfigError as exc:
            last = exc
    raise ConfigError(f"no usable start pose in {MAX_DRAWS} draws for episode {seed}: {last}")


def _episode(args):
    from hvs_sim import plugins
    from hvs_sim.control.laws.ibvs import IBVSConfig
    from hvs_sim.control.safety import SafetyConfig
    from hvs_sim.runner import run_episode
    from hvs_sim.scene.scenarios import CameraConfig

    (scen_name, method, seed, steps, extra, keep, camera, people, damping, template_from, inset, goal_frames, alpha,
     size, tilt, run_as, arm, near_goal, near_goal_scale, safety, goal_template) = args
    episode_threads()
    started = time.perf_counter()
    tracker, warp, controller, policy = parse_method(run_as)
    scen, draws = episode_start(scen_name, seed, tilt, camera=CameraConfig(sensor=camera, width=size[0], height=size[1]),
                                people=people, arm=arm)
    n = steps if steps else scen.n_frames + extra
    tracked = tracker not in (plugins.GROUND_TRUTH, plugins.NO_TRACKER)
    loop_config = LoopConfig(steps=n, keep_frames=False, controller=controller, policy=policy,
                             ibvs=IBVSConfig(damping=damping), template_from=template_from if tracked else None,
                             roi_inset_px=inset, goal_frames=goal_frames if goal_template else None,  # with a goal image
                             feature_filter=alpha if tracked else None,  # ... and with tracked corners
                             near_goal_inset_px=near_goal,  # the scale where the loop's switch can use it
                             near_goal_scale=near_goal_scale,  # where the method takes it (method_plan)
                             safety=SafetyConfig(enabled=safety))
    drawn = time.perf_counter()
    summary, records = run_episode(scen, tracker, loop_config, progress=False, keep_records=keep,
                                   tracker_settings={"warp": warp} if warp else None)
    done = time.perf_counter()
    # where an episode's time went, in its worker: finding the start pose, then the run (its steps and their set-up)
    summary["episode_seconds"] = {"start_pose": drawn - started, "run": done - drawn, "total": done - started,
                                  "steps": summary["steps"] * summary["timing"]["step"]["mean_ms"] / 1e3}
    summary["method"] = method
    summary["episode_seed"] = seed
    summary["start_offset"] = list(scen.start_offset)
    summary["arm"], summary["start_draws"] = arm, draws
    trace = None
    if keep:
        trace = [{"time": r.time, "error_px": r.error_px, "gt_features": r.gt_features.tolist(), "desired": r.desired.tolist(),
                  "twist": r.twist.tolist(), "occlusion": r.occlusion, "pose_error": r.pose_error.tolist(),
                  "condition": r.condition} for r in records]
    return (scen_name, method, seed), summary, trace


def method_results(eps: list[dict], success_px: float) -> dict:
    """One method's figures over its episodes: each success rule with its 95 % Wilson interval, medians with bootstrap
    intervals, and what only an occlusion benchmark reports."""
    from hvs_sim.bench.stats import RULES, episode_success, median_ci, rate

    verdicts = [episode_success(e, success_px) for e in eps]
    success = {rule: rate([v[rule] for v in verdicts]) for rule in RULES}
    conv = [e["seconds_to_converge"] for e in eps if e["converged"]]
    occ = [e["max_error_px_during_occlusion"] for e in eps if e["max_error_px_during_occlusion"] is not None]
    reacq = [e.get("reacquired") for e in eps if e.get("reacquired") is not None]
    # the near-goal template as each episode had it (None, or inset_px None with the reason: one template)
    near = [e.get("near_goal") for e in eps]
    near = [n if n is not None and n.get("inset_px") is not None else None for n in near]
    return {
        "episodes": len(eps), "success": success, "success_rate": success["hvs_sim"]["rate"],
        "reached": rate([e["converged"] for e in eps]), "converged_rate": float(np.mean([e["converged"] for e in eps])),
        "held_rate": float(np.mean([e["held_to_end"] for e in eps])),
        "median_seconds_to_converge": float(np.median(conv)) if conv else None,
        "median_final_error_px": float(np.median([e["final_error_px"] for e in eps])),
        "median_final_pose_error_mm": float(np.median([e["final_pose_error_mm"] for e in eps])),
        "median_final_pose_error_deg": float(np.median([e["final_pose_error_deg"] for e in eps])),
        "final_pose_error_mm": median_ci([e["final_pose_error_mm"] for e in eps]),
        "final_pose_error_deg": median_ci([e["final_pose_error_deg"] for e in eps]),
        "final_error_px": median_ci([e["final_error_px"] for e in eps]),
        "max_final_pose_error_mm": float(np.max([e["final_pose_error_mm"] for e in eps])),
        "max_final_pose_error_deg": float(np.max([e["final_pose_error_deg"] for e in eps])),
        "p95_final_pose_error_mm": float(np.percentile([e["final_pose_error_mm"] for e in eps], 95)),
        "p95_final_pose_error_deg": float(np.percentile([e["final_pose_error_deg"] for e in eps], 95)),
        # the safety rule (control/safety.py; records before it have none of these: counted as none)
        "runaways": int(sum(bool(e.get("runaway")) for e in eps)),
        "aborted": int(sum(e.get("aborted") is not None for e in eps)),
        "mean_held_steps": float(np.mean([e.get("held_steps", 0) for e in eps])),
        "max_drift_while_hidden_mm": median_ci([e.get("max_drift_while_hidden_mm") for e in eps]),
        "worst_drift_while_hidden_mm": _max_or_none([e.get("max_drift_while_hidden_mm") for e in eps]),
        "controlled_dofs": eps[0]["controlled_dofs"],
        "median_camera_path_m": float(np.median([e["camera_path_m"] for e in eps])),
        "episodes_target_left_view": int(sum(e["target_out_of_view_steps"] > 0 for e in eps)),
        "median_max_condition_number": _median_or_none([e["max_condition_number"] for e in eps]),
        "max_final_error_px": float(np.max([e["final_error_px"] for e in eps])),
        "median_max_error_during_occlusion_px": float(np.median(occ)) if occ else None,
        "reacquired": rate(reacq) if reacq else None,
        "seconds_to_reacquire": median_ci([e.get("seconds_to_reacquire") for e in eps]),
        "max_tracker_error_while_hidden_px": median_ci([e.get("max_tracker_error_while_hidden_px") for e in eps]),
        "fault_episodes": int(sum(e["fault_steps"] > 0 for e in eps)),
        "fault_steps": int(sum(e["fault_steps"] for e in eps)),
        "mean_lost_steps": float(np.mean([e["lost_steps"] for e in eps])),
        "mean_predict_steps": float(np.mean([e["predict_steps"] for e in eps])),
        "steps_per_second": float(np.median([e["steps_per_second"] for e in eps])),
        # episodes that switched to the near-goal template (None without one): a run that never switched is the
        # default template's figure under the near-goal's name
        "near_goal_switched": (None if all(n is None for n in near) else
                               int(sum(n is not None and n.get("switched_at_step") is not None for n in near))),
        # why episodes had no near-goal template (the first reason given), so a table says what help a method had
        "near_goal_off": next((e["near_goal"].get("off") for e in eps if isinstance(e.get("near_goal"), dict)
                               and e["near_goal"].get("off")), None),
    }


def throughput(episodes: list[dict], wall_s: float, workers: int) -> dict:
    """Episodes per hour of the whole run as it went (its wall time, with `workers` processes), and where an episode's
    time went (medians over the episodes)."""
    seconds = [e["episode_seconds"] for e in episodes if "episode_seconds" in e]
    return {"episodes": len(episodes), "wall_seconds": wall_s, "workers": workers,
            "episodes_per_hour": 3600.0 * len(episodes) / wall_s if wall_s > 0 else None,
            "median_episode_seconds": {k: float(np.median([s[k] for s in seconds])) for k in seconds[0]}
            if seconds else None}


def run_servo_bench(config: ServoBenchConfig, out: Path, progress: bool = True, resume: bool = False) -> dict:
    from hvs_sim.bench.servo_table import servo_table
    from hvs_sim.bench.stats import RULES
    from hvs_sim.viz.figures import servo_figure

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    provenance = code_provenance()  # the code that runs: read before the episodes, which may take hours
    seeds = config.episode_seeds
    # workers resolve each method again: a name registered in this process travels as its module:callable
    run_as = {m: portable_method(m) if config.workers > 1 else m for m in config.trackers}
    plans = config.method_plans()
    jobs = [(s, t, seed, config.steps, config.extra_steps, seed == seeds[0], config.camera, config.people, config.damping,
             config.template_from, config.roi_inset_px, config.goal_frames, config.feature_filter,
             (config.width, config.height), np.radians(config.tilt_deg), run_as[t], config.arm,
             config.near_goal_inset_px, config.near_goal_scale if plans[t].takes_near_goal_scale else None,
             config.safety, plans[t].goal_template)
            for s in config.scenarios for t in config.trackers for seed in seeds]
    episodes, traces, ran = {}, {}, []
    wall = time.perf_counter()
    for key, summ, trace in collect_jobs(_episode, jobs, config, out, "bench servo", "episode", progress, resume, ran):
        episodes[key], traces[key] = summ, trace
    wall = time.perf_counter() - wall
    lo, hi = offset_range(0.8, np.radians(config.tilt_deg))
    summary = {"schema": RESULTS_SCHEMA, "suite": config.suite, **provenance, "config": config_json(config),
               "success_rules": RULES,
               "offset_range": {"low": lo.tolist(), "high": hi.tolist(),
                                "axes": "dx, dy, dz (m, camera frame), roll, pitch, yaw (rad); standoff 0.8 m",
                                "note": "draws the arm cannot reach or with the target out of view are drawn again"},
               "results": {}, "episodes": [dict(e) for e in episodes.values()],
               # the episodes run now (a resumed run read the others from their records: their time is not in wall)
               "throughput": throughput([episodes[k] for k in ran], wall, config.workers)}
    for s in config.scenarios:
        for t in config.trackers:
            summary["results"].setdefault(s, {})[t] = method_results([episodes[(s, t, seed)] for seed in seeds],
                                                                      config.success_px)
        servo_figure({t: traces[(s, t, seeds[0])] for t in config.trackers}, out / f"servo_{s}.png",
                     f"{s}, seed {seeds[0]}: error to s*, true corner paths, pose error, camera velocity")
    write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    write_atomic(out / "table.md", servo_table(summary, config))
    return summary
