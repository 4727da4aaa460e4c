"""`hvs-sim bench track`: the paper's Section 4 in simulation.

Every (scenario, mount, seed) sequence is rendered once and given to every method. Per frame:
e_xy = ‖t_est − t_gt‖ (pixels), true occlusion, mode, ms. Outputs: summary.json, frames.csv,
per-scenario Fig. 7 triads (CDF, error over time with occlusion shaded, error vs occlusion) and
table.md.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hvs_sim.bench.pool import collect_jobs, config_json, episode_threads, write_frames_csv
from hvs_sim.bench.sequences import Sequence, make_sequence
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.outputs import write_atomic
from hvs_sim.sensor import REALISTIC_PRESET
from hvs_sim.validate import check_number

# the methods and the hybrid's ablations a default run compares (any name of tracking/registry.py is accepted)
METHODS = ("sift", "ecc", "deep_lk", "deep_lk_residual", "hybrid", "hybrid_paper", "hybrid_grey", "hybrid_no_anchor",
           "hybrid_cv", "hybrid_residual", "hybrid_raw_op")
SCENARIOS = ("clear", "walk_by", "pause", "partial", "two_people")
OCCLUSION_SCENARIOS = ("walk_by", "pause", "partial", "two_people")
# the tracking issue's target set: hand-held walk_by, pause and partial (peak occlusion >= 90 % or long partial)
TARGET_SET = (("walk_by", "pause", "partial"), "handheld")


def tracker_for(method: str):
    """A fresh tracker for a benchmark method: a name of the tracker registry (tracking/registry.py) or an outside
    tracker (hvs_sim.plugins)."""
    from hvs_sim.plugins import make_any_tracker

    return make_any_tracker(method)


def run_tracker(method: str, seq: Sequence) -> dict[str, np.ndarray]:
    """Per-frame arrays: error (px), ms, mode, OP_t estimate, score (frame 0 is the init frame)."""
    tracker = tracker_for(method)
    tracker.init(seq.frames[0], seq.roi)
    gt = seq.gt_track
    err, ms, mode, occ_est = [0.0], [0.0], ["init"], [0.0]
    from hvs_sim.external import ExternalTracker

    # an outside tracker's failure on a frame is recorded (its estimate held, the frame counted lost); a built-in's
    # is a bug, and raises
    faults = (Exception,) if isinstance(tracker, ExternalTracker) else ()
    centre = gt[0]
    for k in range(1, len(seq.frames)):
        try:
            tk = tracker.update(seq.frames[k])
        except faults:
            err.append(float(np.linalg.norm(centre - gt[k])))
            ms.append(0.0)
            mode.append("lost")
            occ_est.append(0.0)
            continue
        centre = tk.center
        err.append(float(np.linalg.norm(tk.center - gt[k])))
        ms.append(tk.ms)
        mode.append(tk.mode)
        occ_est.append(tk.occlusion)
    return {"error": np.array(err), "ms": np.array(ms), "mode": np.array(mode), "occ_est": np.array(occ_est),
            "occlusion": seq.occlusion}


def summarize(results: list[dict[str, np.ndarray]], mask_fn=None) -> dict[str, float]:
    """Figures over all frames after the init frame (optionally only where mask_fn(result) is True)."""
    sel = [np.ones(len(r["error"]) - 1, bool) if mask_fn is None else mask_fn(r)[1:] for r in results]
    err = np.concatenate([r["error"][1:][m] for r, m in zip(results, sel)])
    ms = np.concatenate([r["ms"][1:][m] for r, m in zip(results, sel)])
    modes = np.concatenate([r["mode"][1:][m] for r, m in zip(results, sel)])
    if err.size == 0:
        return {"frames": 0}
    return {
        "frames": int(err.size),
        "pct_le_1px": float(100 * np.mean(err <= 1.0)),
        "pct_le_2px": float(100 * np.mean(err <= 2.0)),
        "median_px": float(np.median(err)),
        "p95_px": float(np.percentile(err, 95)),
        "max_px": float(err.max()),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "pct_lost": float(100 * np.mean(modes == "lost")),
        "pct_predict": float(100 * np.mean(modes == "predict")),
    }


@dataclass(frozen=True)
class TrackBenchConfig:
    methods: tuple[str, ...] = METHODS
    scenarios: tuple[str, ...] = SCENARIOS
    mounts: tuple[str, ...] = ("handheld", "arm")
    seeds: tuple[int, ...] = (100, 101, 102)
    frames: int | None = None  # None: the scenario's full length
    workers: int = 1
    camera: str = REALISTIC_PRESET  # camera model of every sequence (hvs_sim.sensor.SENSOR_PRESETS)
    people: str = "textured"  # how the people look ("plain": the flat figures of the earlier benchmarks)

    def __post_init__(self):
        from hvs_sim.plugins import check_any_tracker, probe
        from hvs_sim.scene.scenarios import MOUNTS, PEOPLE_STYLES, SCENARIO_NAMES
        from hvs_sim.sensor import sensor_preset

        if not self.methods:
            raise ConfigError("the tracking benchmark needs at least one tracker")
        for m in self.methods:
            check_any_tracker(m)
            probe("tracker", m)  # an outside tracker built once: a broken factory is found before any sequence
        for what, values, accepted in (("scenario", self.scenarios, SCENARIO_NAMES),
                                       ("mount", self.mounts, MOUNTS), ("people style", (self.people,), PEOPLE_STYLES)):
            if not values:
                raise ConfigError(f"the tracking benchmark needs at least one {what}; accepted: {', '.join(accepted)}")
            for v in values:
                if v not in accepted:
                    raise choice_error(what, v, accepted)
        for s in self.seeds:
            check_number("seed", s, 0, integer=True)
        if self.frames is not None:
            check_number("frames", self.frames, 2, integer=True)
        check_number("workers", self.workers, 1, integer=True)
        sensor_preset(self.camera)


def _job(args):
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    scen, mount, seed, frames, methods, camera, people = args
    episode_threads()
    scenario = make_scenario(scen, mount=mount, seed=seed, camera=CameraConfig(sensor=camera), people=people)
    seq = make_sequence(scenario, n_frames=frames)
    return (scen, mount, seed), {m: run_tracker(m, seq) for m in methods}


def run_track_bench(config: TrackBenchConfig, out: Path, progress: bool = True, resume: bool = False) -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    from hvs_sim.plugins import portable

    # workers resolve each tracker again: a name registered in this process travels as its module:callable
    run_as = tuple(portable("tracker", m) if config.workers > 1 else m for m in config.methods)
    jobs = [(s, m, seed, config.frames, run_as, config.camera, config.people) for s in config.scenarios for m in config.mounts for seed in config.seeds]
    results = {k: dict(zip(config.methods, per.values(), strict=True))
               for k, per in collect_jobs(_job, jobs, config, out, "bench track", "sequence", progress, resume)}
    summary = {"config": config_json(config),
               "per_scenario": {}, "occlusion_scenarios": {}, "target_set": {}, "overall": {}}
    for m in config.methods:
        for s in config.scenarios:
            rs = [results[k][m] for k in results if k[0] == s]
            summary["per_scenario"].setdefault(s, {})[m] = summarize(rs)
        occ = [results[k][m] for k in results if k[0] in OCCLUSION_SCENARIOS]
        if occ:
            summary["occlusion_scenarios"][m] = {
                "all": summarize(occ),
                "visible_lt_40": summarize(occ, lambda r: r["occlusion"] < 0.4),
                "occluded_ge_40": summarize(occ, lambda r: r["occlusion"] >= 0.4),
            }
        target = [results[k][m] for k in results if k[0] in TARGET_SET[0] and k[1] == TARGET_SET[1]]
        if target:
            summary["target_set"][m] = {"all": summarize(target),
                                        "visible_lt_40": summarize(target, lambda r: r["occlusion"] < 0.4)}
        summary["overall"][m] = summarize([results[k][m] for k in results])
    write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    write_frames_csv(results, out / "frames.csv", ("scenario", "mount", "seed"))
    from hvs_sim.viz.figures import track_triads

    track_triads(results, config, out)
    write_atomic(out / "table.md", track_table(summary))
    return summary


def track_table(summary: dict) -> str:
    lines = ["| method | frames | ≤1 px | ≤2 px | median px | p95 px | max px | median ms | p95 ms | lost | predict |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]

    def row(name, s):
        return (f"| {name} | {s['frames']} | {s['pct_le_1px']:.1f} % | {s['pct_le_2px']:.1f} % | {s['median_px']:.2f} | "
                f"{s['p95_px']:.2f} | {s['max_px']:.1f} | {s['median_ms']:.1f} | {s['p95_ms']:.1f} | {s['pct_lost']:.1f} % | "
                f"{s['pct_predict']:.1f} % |")

    text = []
    if summary.get("target_set"):
        text += ["## Target set: hand-held walk_by, pause, partial — all frames", "", *lines]
        text += [row(m, v["all"]) for m, v in summary["target_set"].items()]
        text += ["", "## Target set, frames with true occlusion < 40 %", "", *lines]
        text += [row(m, v["visible_lt_40"]) for m, v in summary["target_set"].items() if v["visible_lt_40"]["frames"]]
        text += [""]
    text += ["## Occlusion scenarios (walk_by, pause, partial, two_people; hand-held and arm), all frames", "", *lines]
    text += [row(m, v["all"]) for m, v in summary["occlusion_scenarios"].items()]
    text += ["", "## Occlusion scenarios, frames with true occlusion < 40 %", "", *lines]
    text += [row(m, v["visible_lt_40"]) for m, v in summary["occlusion_scenarios"].items() if v["visible_lt_40"]["frames"]]
    for s, per in summary["per_scenario"].items():
        text += ["", f"## {s}", "", *lines, *[row(m, v) for m, v in per.items() if v.get("frames")]]
    return "\n".join(text) + "\n"
