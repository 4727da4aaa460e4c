"""`hvs-sim bench servo`: closed-loop convergence under occlusion from random initial offsets."""

from __future__ import annotations

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

SERVO_TRACKERS = ("ground_truth", "hybrid", "deep_lk_residual", "deep_lk", "ecc")
# initial offsets (camera frame): x, y within ±4 cm, depth −4…+10 cm, roll within ±0.25 rad
OFFSET_LOW = np.array([-0.04, -0.04, -0.04, -0.25])
OFFSET_HIGH = np.array([0.04, 0.04, 0.10, 0.25])


EXTRA_STEPS = 60  # an episode runs this long past the scenario's end, to see the recovery
SUCCESS_PX = 1.0  # success = converged and final ground-truth error ≤ this


@dataclass(frozen=True)
class ServoBenchConfig:
    trackers: tuple[str, ...] = SERVO_TRACKERS
    scenarios: tuple[str, ...] = ("walk_by", "pause")
    episodes: int = 10
    seed0: int = 200
    extra_steps: int = EXTRA_STEPS
    steps: int | None = None  # overrides scenario length + extra_steps (smoke runs)
    success_px: float = SUCCESS_PX
    workers: int = 1
    camera: str = REALISTIC_PRESET  # camera model of every episode (hvs_sim.camera_model.SENSOR_PRESETS)
    people: str = "textured"  # how the people look ("plain": the flat figures of the earlier benchmarks)
    seeds: tuple[int, ...] | None = None  # explicit episode seeds (then `episodes` and `seed0` are not used)

    def __post_init__(self):
        from hvs_sim.camera_model import sensor_preset
        from hvs_sim.loop import LOOP_TRACKERS
        from hvs_sim.scene.scenarios import PEOPLE_STYLES, SCENARIO_NAMES

        for what, values, accepted in (("tracker", self.trackers, LOOP_TRACKERS), ("scenario", self.scenarios, SCENARIO_NAMES),
                                       ("people style", (self.people,), PEOPLE_STYLES)):
            if not values:
                raise ConfigError(f"the servo benchmark needs at least one {what}; accepted: {', '.join(accepted)}")
            for v in values:
                if v not in accepted:
                    raise choice_error(what, v, accepted)
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

    @property
    def episode_seeds(self) -> list[int]:
        return list(self.seeds) if self.seeds is not None else [self.seed0 + i for i in range(self.episodes)]


def episode_offset(seed: int) -> tuple[float, ...]:
    rng = np.random.default_rng([seed, 11])
    return tuple(float(v) for v in rng.uniform(OFFSET_LOW, OFFSET_HIGH))


def _episode(args):
    import torch

    from hvs_sim.runner import run_episode
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    scen_name, tracker, seed, steps, extra, keep, camera, people = args
    torch.set_num_threads(1 if os.environ.get("HVS_WORKERS", "1") != "1" else 2)
    scen = make_scenario(scen_name, mount="arm", seed=seed, start_offset=episode_offset(seed),
                         camera=CameraConfig(sensor=camera), people=people)
    n = steps if steps else scen.n_frames + extra
    summary, records = run_episode(scen, tracker, LoopConfig(steps=n, keep_frames=False), progress=False)
    summary["start_offset"] = list(scen.start_offset)
    trace = None
    if keep:
        trace = [{"time": r.time, "error_px": r.error_px, "gt_features": r.gt_features.tolist(), "desired": r.desired.tolist(),
                  "twist": r.twist.tolist(), "occlusion": r.occlusion} for r in records]
    return (scen_name, tracker, seed), summary, trace


def run_servo_bench(config: ServoBenchConfig, out: Path, progress: bool = True) -> dict:
    from hvs_sim.viz.figures import servo_figure

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = config.episode_seeds
    jobs = [(s, t, seed, config.steps, config.extra_steps, seed == seeds[0], config.camera, config.people)
            for s in config.scenarios for t in config.trackers for seed in seeds]
    os.environ["HVS_WORKERS"] = str(config.workers)
    episodes, traces = {}, {}
    for key, summ, trace in collect_jobs(_episode, jobs, config, out, "bench servo", "episode", progress):
        episodes[key], traces[key] = summ, trace
    summary = {"config": config_json(config),
               "offset_range": {"low": OFFSET_LOW.tolist(), "high": OFFSET_HIGH.tolist(),
                                "axes": "dx, dy, dz (m, camera frame), roll (rad)"},
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
                "max_final_error_px": float(np.max([e["final_error_px"] for e in eps])),
                "median_max_error_during_occlusion_px": float(np.median(occ)) if occ else None,
                "mean_lost_steps": float(np.mean([e["lost_steps"] for e in eps])),
                "mean_predict_steps": float(np.mean([e["predict_steps"] for e in eps])),
                "steps_per_second": float(np.median([e["steps_per_second"] for e in eps])),
            }
        servo_figure({t: traces[(s, t, seeds[0])] for t in config.trackers}, out / f"servo_{s}.png",
                     f"{s}, seed {seeds[0]}: error to s*, true corner paths, camera velocity")
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    (out / "table.md").write_text(servo_table(summary, config))
    return summary


def servo_table(summary: dict, config: ServoBenchConfig) -> str:
    lines = []
    for s, per in summary["results"].items():
        lines += [f"## {s} ({len(config.episode_seeds)} episodes per tracker, success = converged and final error ≤ {config.success_px} px)", "",
                  ("| tracker | success | converged | median time to converge (s) | median final error (px) | max final error (px) "
                  "| median max error in occlusion (px) | lost steps | predict steps | steps/s |"),
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for t, r in per.items():
            conv_t = "–" if r["median_seconds_to_converge"] is None else f"{r['median_seconds_to_converge']:.2f}"
            occ = "–" if r["median_max_error_during_occlusion_px"] is None else f"{r['median_max_error_during_occlusion_px']:.1f}"
            lines.append(f"| {t} | {100 * r['success_rate']:.0f} % | {100 * r['converged_rate']:.0f} % | {conv_t} | "
                         f"{r['median_final_error_px']:.2f} | {r['max_final_error_px']:.2f} | {occ} | {r['mean_lost_steps']:.1f} | "
                         f"{r['mean_predict_steps']:.1f} | {r['steps_per_second']:.1f} |")
        lines.append("")
    return "\n".join(lines)
