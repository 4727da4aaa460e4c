"""`hvs-sim bench servo`: closed-loop convergence under occlusion from random 6-DOF start poses.

A method is a loop tracker with, optionally, its warp model and the servo law:
`TRACKER[:homography][/pbvs]`, e.g. `ground_truth`, `ground_truth/pbvs`, `hybrid:homography`, `hybrid`
(the similarity hybrid, which controls 4 DOF). Start poses are drawn over the ranges of the classic
IBVS test cases (ViSP's tutorials, Chaumette's examples), scaled to the 0.8 m standoff: lateral
±10 cm, target depth 0.7–1.4 × the standoff, roll ±60°, pitch and yaw ±15°; a draw the arm cannot reach or
from which the target is not fully in view is drawn again (seeded)."""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hvs_sim.bench.pool import collect_jobs, config_json
from hvs_sim.camera_model import REALISTIC_PRESET
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.loop import LoopConfig
from hvs_sim.validate import check_number

SERVO_METHODS = ("ground_truth", "ground_truth/pbvs", "hybrid:homography", "hybrid:homography/pbvs", "hybrid")
# start offsets (camera frame): dx, dy (m), the target's depth as a share of the standoff, roll, pitch, yaw (rad).
# Results before stop 30 (servo_6dof_v4 and older) were drawn over a depth of 0.6-1.3 (a sign slip, found in review)
LATERAL_M, DEPTH_RANGE = 0.10, (0.7, 1.4)
ROLL_MAX, TILT_MAX = np.radians(60.0), np.radians(15.0)
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
    seeds: tuple[int, ...] | None = None  # explicit episode seeds (then `episodes` and `seed0` are not used)
    damping: float | None = None  # IBVSConfig.damping of every episode (None: the loop's default)
    template_from: str | None = None  # LoopConfig.template_from of every episode (None: the loop's default)
    roi_inset_px: int | None = None  # LoopConfig.roi_inset_px of every episode (None: the loop's default)
    goal_frames: int | None = None  # LoopConfig.goal_frames of the episodes with a goal template (None: the loop's default)
    feature_filter: float | None = None  # LoopConfig.feature_filter of the episodes with tracked corners (None: default)

    def __post_init__(self):
        from hvs_sim.camera_model import sensor_preset
        from hvs_sim.loop import LOOP_TRACKERS
        from hvs_sim.scene.scenarios import PEOPLE_STYLES, SCENARIO_NAMES
        from hvs_sim.tracking import check_tracker

        for what, values, accepted in (("tracker", [parse_method(m)[0] for m in self.trackers], LOOP_TRACKERS),
                                       ("scenario", self.scenarios, SCENARIO_NAMES),
                                       ("people style", (self.people,), PEOPLE_STYLES)):
            if not values:
                raise ConfigError(f"the servo benchmark needs at least one {what}; accepted: {', '.join(accepted)}")
            for v in values:
                if v not in accepted:
                    raise choice_error(what, v, accepted)
        for m in self.trackers:  # e.g. a residual tracker with a homography: refused here, not in a worker
            tracker, warp, _ = parse_method(m)
            if warp:
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
        if self.damping is not None:
            check_number("damping", self.damping, 0, 1)
        LoopConfig(template_from=self.template_from, roi_inset_px=self.roi_inset_px, goal_frames=self.goal_frames,
                   feature_filter=self.feature_filter)  # checks them
        if self.goal_frames is not None and self.template_from == "start":
            raise ConfigError(f"goal_frames ({self.goal_frames}) averages frames into a goal image; with template_from "
                              "'start' no episode has one: leave one of them out")

    @property
    def episode_seeds(self) -> list[int]:
        return list(self.seeds) if self.seeds is not None else [self.seed0 + i for i in range(self.episodes)]


def _median_or_none(values) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.median(vals)) if vals else None


def parse_method(method: str) -> tuple[str, str | None, str]:
    """`TRACKER[:WARP][/CONTROLLER]` → (tracker, warp or None, controller)."""
    from hvs_sim.control.ibvs import CONTROLLERS
    from hvs_sim.tracking.warp import WARPS

    rest, _, controller = method.partition("/")
    tracker, _, warp = rest.partition(":")
    controller = controller or "ibvs"
    if controller not in CONTROLLERS or (warp and warp not in WARPS) or (warp and tracker == "ground_truth"):
        raise ConfigError(f"servo method {method!r} invalid; accepted: TRACKER[:WARP][/CONTROLLER] with WARP one of "
                          f"{', '.join(WARPS)} (not for ground_truth) and CONTROLLER one of {', '.join(CONTROLLERS)}, "
                          "e.g. hybrid:homography/pbvs")
    return tracker, warp or None, controller


def offset_range(standoff: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of (dx, dy, dz, roll, pitch, yaw); dz > 0 moves the camera towards the target."""
    lo = np.array([-LATERAL_M, -LATERAL_M, (1 - DEPTH_RANGE[1]) * standoff, -ROLL_MAX, -TILT_MAX, -TILT_MAX])
    hi = np.array([LATERAL_M, LATERAL_M, (1 - DEPTH_RANGE[0]) * standoff, ROLL_MAX, TILT_MAX, TILT_MAX])
    return lo, hi


def episode_offset(seed: int, standoff: float = 0.8, draw: int = 0) -> tuple[float, ...]:
    """The `draw`-th candidate start offset of episode `seed` (dx, dy, dz m; roll, pitch, yaw rad)."""
    rng = np.random.default_rng([seed, 11, draw])
    return tuple(float(v) for v in rng.uniform(*offset_range(standoff)))


def episode_scenario(scen_name: str, seed: int, **overrides):
    """The episode's scenario with the first drawn start pose that the arm reaches and from which
    the target is fully in view (the same for every method of that seed)."""
    from hvs_sim.loop import check_start_pose
    from hvs_sim.scene.scenarios import make_scenario

    last = None
    base = make_scenario(scen_name, mount="arm", seed=seed, **overrides)
    for draw in range(MAX_DRAWS):
        scen = dataclasses.replace(base, start_offset=episode_offset(seed, base.standoff, draw))
        try:
            check_start_pose(scen)
            return scen
        except ConfigError as exc:
            last = exc
    raise ConfigError(f"no usable start pose in {MAX_DRAWS} draws for episode {seed}: {last}")


def _episode(args):
    import torch

    from hvs_sim.control.ibvs import IBVSConfig
    from hvs_sim.loop import template_view
    from hvs_sim.runner import run_episode
    from hvs_sim.scene.scenarios import CameraConfig

    scen_name, method, seed, steps, extra, keep, camera, people, damping, template_from, inset, goal_frames, alpha = args
    torch.set_num_threads(1 if os.environ.get("HVS_WORKERS", "1") != "1" else 2)
    tracker, warp, controller = parse_method(method)
    scen = episode_scenario(scen_name, seed, camera=CameraConfig(sensor=camera), people=people)
    n = steps if steps else scen.n_frames + extra
    tracked = tracker != "ground_truth"
    goal_template = tracked and template_view(template_from, tracked and warp == "homography") == "goal"
    loop_config = LoopConfig(steps=n, keep_frames=False, controller=controller, ibvs=IBVSConfig(damping=damping),
                             template_from=template_from, roi_inset_px=inset,
                             goal_frames=goal_frames if goal_template else None,  # the episodes with a goal image
                             feature_filter=alpha if tracked else None)  # ... and with tracked corners
    summary, records = run_episode(scen, tracker, loop_config, progress=False, keep_records=keep,
                                   tracker_settings={"warp": warp} if warp else None)
    summary["method"] = method
    summary["start_offset"] = list(scen.start_offset)
    trace = None
    if keep:
        trace = [{"time": r.time, "error_px": r.error_px, "gt_features": r.gt_features.tolist(), "desired": r.desired.tolist(),
                  "twist": r.twist.tolist(), "occlusion": r.occlusion, "pose_error": r.pose_error.tolist(),
                  "condition": r.condition} for r in records]
    return (scen_name, method, seed), summary, trace


def run_servo_bench(config: ServoBenchConfig, out: Path, progress: bool = True) -> dict:
    from hvs_sim.viz.figures import servo_figure

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = config.episode_seeds
    jobs = [(s, t, seed, config.steps, config.extra_steps, seed == seeds[0], config.camera, config.people, config.damping,
             config.template_from, config.roi_inset_px, config.goal_frames, config.feature_filter)
            for s in config.scenarios for t in config.trackers for seed in seeds]
    os.environ["HVS_WORKERS"] = str(config.workers)
    episodes, traces = {}, {}
    for key, summ, trace in collect_jobs(_episode, jobs, config, out, "bench servo", "episode", progress):
        episodes[key], traces[key] = summ, trace
    lo, hi = offset_range(0.8)
    summary = {"config": config_json(config),
               "offset_range": {"low": lo.tolist(), "high": hi.tolist(),
                                "axes": "dx, dy, dz (m, camera frame), roll, pitch, yaw (rad); standoff 0.8 m",
                                "note": "draws the arm cannot reach or with the target out of view are drawn again"},
               "results": {}, "episodes": [dict(e) for e in episodes.values()]}
    for s in config.scenarios:
        for t in config.trackers:
            eps = [episodes[(s, t, seed)] for seed in seeds]
            ok = [e["converged"] and e["final_error_px"] <= config.success_px for e in eps]
            conv = [e["seconds_to_converge"] for e in eps if e["converged"]]
            occ = [e["max_error_px_during_occlusion"] for e in eps if e["max_error_px_during_occlusion"] is not None]
            summary["results"].setdefault(s, {})[t] = {
                "episodes": len(eps), "success_rate": float(np.mean(ok)),
                "converged_rate": float(np.mean([e["converged"] for e in eps])),
                "median_seconds_to_converge": float(np.median(conv)) if conv else None,
                "median_final_error_px": float(np.median([e["final_error_px"] for e in eps])),
                "median_final_pose_error_mm": float(np.median([e["final_pose_error_mm"] for e in eps])),
                "median_final_pose_error_deg": float(np.median([e["final_pose_error_deg"] for e in eps])),
                "max_final_pose_error_mm": float(np.max([e["final_pose_error_mm"] for e in eps])),
                "max_final_pose_error_deg": float(np.max([e["final_pose_error_deg"] for e in eps])),
                "controlled_dofs": eps[0]["controlled_dofs"],
                "median_camera_path_m": float(np.median([e["camera_path_m"] for e in eps])),
                "episodes_target_left_view": int(sum(e["target_out_of_view_steps"] > 0 for e in eps)),
                "median_max_condition_number": _median_or_none([e["max_condition_number"] for e in eps]),
                "max_final_error_px": float(np.max([e["final_error_px"] for e in eps])),
                "median_max_error_during_occlusion_px": float(np.median(occ)) if occ else None,
                "mean_lost_steps": float(np.mean([e["lost_steps"] for e in eps])),
                "mean_predict_steps": float(np.mean([e["predict_steps"] for e in eps])),
                "steps_per_second": float(np.median([e["steps_per_second"] for e in eps])),
            }
        servo_figure({t: traces[(s, t, seeds[0])] for t in config.trackers}, out / f"servo_{s}.png",
                     f"{s}, seed {seeds[0]}: error to s*, true corner paths, pose error, camera velocity")
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    (out / "table.md").write_text(servo_table(summary, config))
    return summary


def _fmt(v, spec: str) -> str:
    return "–" if v is None else format(v, spec)


def servo_table(summary: dict, config: ServoBenchConfig) -> str:
    lines = []
    for s, per in summary["results"].items():
        lines += [(f"## {s} ({len(config.episode_seeds)} episodes per method; success = converged (image error and the "
                  f"pose error in the controlled DOFs under their bounds) and final error ≤ {config.success_px} px)"), "",
                  ("| method | DOFs | success | converged | median time to converge (s) | median final error (px) "
                   "| median final pose error (mm / °) | max final pose error (mm / °) | camera path (m) "
                   "| target left view | median max error in occlusion (px) | median max cond(L) | steps/s |"),
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for t, r in per.items():
            conv_t = "–" if r["median_seconds_to_converge"] is None else f"{r['median_seconds_to_converge']:.2f}"
            occ = "–" if r["median_max_error_during_occlusion_px"] is None else f"{r['median_max_error_during_occlusion_px']:.1f}"
            lines.append(f"| {t} | {len(r['controlled_dofs'])} | {100 * r['success_rate']:.0f} % | {100 * r['converged_rate']:.0f} % "
                         f"| {conv_t} | {r['median_final_error_px']:.2f} | {r['median_final_pose_error_mm']:.1f} / "
                         f"{r['median_final_pose_error_deg']:.2f} | {r['max_final_pose_error_mm']:.1f} / "
                         f"{r['max_final_pose_error_deg']:.2f} | {r['median_camera_path_m']:.2f} | "
                         f"{r['episodes_target_left_view']} of {r['episodes']} | {occ} | "
                         f"{_fmt(r['median_max_condition_number'], '.0f')} | {r['steps_per_second']:.1f} |")
        lines.append("")
    return "\n".join(lines)
