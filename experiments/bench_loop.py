"""Closed-loop speed as a user runs it: per-stage ms and steps/s of the demo run (from each step's wall time, with
its recording), with and without evaluation; the hybrid's ms in that loop against the same hybrid replayed alone on
the very frames and template the loop gave it; each camera preset's render cost against `ideal`'s; and the hybrid's
ms beside the ECC baseline's on the same frames, all in one process.

    python experiments/bench_loop.py --out experiments/results/loop_speed

`--camera-pairs 2 --configs` (no configuration named) runs only the demo's loop through `ideal` and `phone_handheld`
in turn, twice, and writes their steps/s ratio pair by pair to speed.json.

Writes speed.json and speed.md there (docs/results.md's loop-speed figures come from them). Run it on a quiet
machine: the steps/s are absolute figures of this machine; the ratios are what carries across machines.

Configurations (walk_by on the arm, seed 0, the hybrid, 640×480, 240 steps, as `make demo`):
  as_run         evaluation on, .rrd recording with frames, JSON + CSV (what `make demo` does)
  no_eval        evaluate=False (no segmentation render), no recording
  pipelined      as_run with LoopConfig(pipeline=True): frame k tracked while frame k + 1 renders
  pipelined_no_eval  no_eval, pipelined
  as_run_ms4     as_run with 4× multisampling (the render setting before it became a choice)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from hvs_sim.bench.sequences import make_sequence
from hvs_sim.bench.track import run_tracker
from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.sensor import sensor_preset
from hvs_sim.servo.config import LoopConfig
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.base import Tracker

sys.path.insert(0, str(Path(__file__).parent))
from bench_render import VARIANTS, time_presets

STAGES = ("render", "ground_truth", "track", "control", "physics", "log", "other")
PRESET_FRAMES = 100  # walk_by hand-held frames per camera preset (the person crosses from frame ~60)


def loop_run(name: str, steps: int, evaluate: bool, rrd: bool, multisample: int | None, pipeline: bool, tmp: Path,
             keep: bool = False, camera: str = "ideal") -> dict:
    preset, _, variant = camera.partition(":")  # "phone_handheld:small": bench_render's VARIANTS
    sensor = sensor_preset(preset, **(VARIANTS[variant] if variant else {}))
    base = make_scenario("walk_by", mount="arm", seed=0, camera=CameraConfig(sensor=sensor))
    scen = base if multisample is None else dataclasses.replace(
        base, camera=dataclasses.replace(base.camera, multisample=multisample))
    cfg = LoopConfig(steps=steps, evaluate=evaluate, keep_frames=rrd, pipeline=pipeline)
    t0 = time.perf_counter()
    summary, records = run_episode(scen, "hybrid", cfg, rrd=str(tmp / f"{name}.rrd") if rrd else None,
                                   json_path=str(tmp / f"{name}.json"), progress=False, keep_records=True)
    wall = time.perf_counter() - t0
    t = summary["timing"]
    step_ms = np.array([r.wall_ms for r in records])
    return {"evaluate": evaluate, "rrd": rrd, "multisample": scen.camera.multisample, "pipeline": pipeline,
            "median_ms": {k: t[k]["median_ms"] for k in STAGES if "median_ms" in t.get(k, {})},
            "mean_ms": {k: t[k]["mean_ms"] for k in STAGES if k in t},
            "recording_thread_cpu_ms": t.get("recording_thread", {}).get("mean_ms"),
            "steps_per_second": summary["steps_per_second"],  # as run.json reports it: every step, the first too
            "steps_per_second_after_first": float(1e3 / step_ms[1:].mean()),
            "first_step_ms": float(step_ms[0]),
            "wall_seconds_with_setup": wall, "converged": summary["converged"],
            "final_error_px": summary["final_error_px"]}


class _Taped:
    """Tracker.init / seed / update patched to keep what the loop gave the tracker and each update's ms."""

    def __init__(self):
        self.calls, self.ms, self._orig = [], [], (Tracker.init, Tracker.seed, Tracker.update)

    def __enter__(self):
        init, seed, update = self._orig
        tape = self

        def taped_update(tracker, frame):
            tape.calls.append(("update", frame.copy()))
            t = time.perf_counter()
            out = update(tracker, frame)
            tape.ms.append(1e3 * (time.perf_counter() - t))
            return out

        Tracker.init = lambda tr, frame, roi: (self.calls.append(("init", frame.copy(), roi)), init(tr, frame, roi))[1]
        Tracker.seed = lambda tr, corners: (self.calls.append(("seed", np.array(corners))), seed(tr, corners))[1]
        Tracker.update = taped_update
        return self

    def __exit__(self, *exc):
        Tracker.init, Tracker.seed, Tracker.update = self._orig


def tracker_in_loop(steps: int, tmp: Path) -> dict:
    """The hybrid's update ms inside the demo's loop (as run: evaluation and recording on) against the same tracker
    replayed alone on the frames, template and seed the loop gave it (twice; the second, warm, replay counts)."""
    with _Taped() as tape:
        loop_run("taped", steps, True, True, None, False, tmp)
    replays = []
    for _ in range(2):
        tracker, ms = make_tracker("hybrid"), []
        for call in tape.calls:
            if call[0] == "init":
                tracker.init(call[1], call[2])
            elif call[0] == "seed":
                tracker.seed(call[1])
            else:
                t = time.perf_counter()
                tracker.update(call[1])
                ms.append(1e3 * (time.perf_counter() - t))
        replays.append(ms)
    in_loop, alone = float(np.median(tape.ms)), float(np.median(replays[-1]))
    return {"frames": len(tape.ms), "in_loop_median_ms": in_loop, "isolated_median_ms": alone,
            "in_loop_mean_ms": float(np.mean(tape.ms)), "isolated_mean_ms": float(np.mean(replays[-1])),
            "in_loop_over_isolated": in_loop / alone}


def preset_costs(frames: int) -> dict:
    """Mean ms of an RGB frame through each camera preset (bench_render's interleaved timing), its ratio to `ideal`'s."""
    from hvs_sim.sensor import SENSOR_NAMES

    out, _ = time_presets({name: (name, None) for name in SENSOR_NAMES}, frames)
    out["realistic_mean_ratio_to_ideal"] = float(np.mean([p["ratio_to_ideal"] for n, p in out.items()
                                                          if n != "ideal"]))
    return out


def camera_loops(pairs: int, steps: int, config: tuple, cameras: tuple[str, ...], tmp: Path) -> dict:
    """The demo's loop (walk_by on the arm, seed 0, the hybrid) through each camera of `cameras`, run in turn `pairs`
    times (A B A B …, so that the machine's drift falls on both), with each camera's steps/s over the first's, run by
    run; `config`: (evaluate, rrd, multisample, pipeline) as in main's table."""
    runs = {c: [] for c in cameras}
    for k in range(pairs):
        for camera in cameras:
            runs[camera].append(loop_run(f"{camera}_{k}", steps, *config, tmp, camera=camera))
            r = runs[camera][-1]
            print(f"loop through {camera:16s} run {k}: {r['steps_per_second']:.1f} steps/s as run, "
                  f"{r['steps_per_second_after_first']:.1f} after step 0, render {r['mean_ms'].get('render', 0):.1f} ms"
                  f" | converged {r['converged']} {r['final_error_px']:.2f} px", flush=True)
    out = {"pairs": pairs, "config": dict(zip(("evaluate", "rrd", "multisample", "pipeline"), config)), "runs": runs}
    base = runs[cameras[0]]
    for camera in cameras[1:]:
        ratios = [b["steps_per_second_after_first"] / a["steps_per_second_after_first"]
                  for a, b in zip(base, runs[camera])]
        out[f"{camera}_over_{cameras[0]}_steps_per_second"] = ratios
        print(f"{camera} loop / {cameras[0]} loop, steps/s after step 0, pair by pair: "
              + ", ".join(f"{x:.2f}" for x in ratios), flush=True)
    return out


def tracker_timing(frames: int) -> dict:
    """Median ms per 640×480 frame of the hybrid and ECC on the same hand-held walk_by frames."""
    seq = make_sequence(make_scenario("walk_by", mount="handheld", seed=100), n_frames=frames)
    out = {}
    for method in ("ecc", "hybrid"):
        res = run_tracker(method, seq)
        ms = np.asarray(res["ms"][1:], float)  # frame 0 is the init
        out[method] = {"median_ms": float(np.median(ms)), "p95_ms": float(np.percentile(ms, 95))}
    out["hybrid_over_ecc"] = out["hybrid"]["median_ms"] / out["ecc"]["median_ms"]
    return out


def markdown(res: dict) -> str:
    lines = ["| configuration | " + " | ".join(STAGES) + " | steps/s (all) | steps/s (after step 0) | converged | final px |",
             "|---" * (len(STAGES) + 5) + "|"]
    for name, r in res["loop"].items():
        cells = [f"{r['mean_ms'][k]:.1f}" if k in r["mean_ms"] else "—" for k in STAGES]
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {r['steps_per_second']:.1f} | "
                     f"{r['steps_per_second_after_first']:.1f} | {r['converged']} | {r['final_error_px']:.2f} |")
    lines += ["", ("Mean ms per step. steps/s from each step's wall time (the recording and the CSV included; step 0 "
                   "holds the set-up: the GL context, the goal image, the tracker's template). Pipelined: render, "
                   "ground truth and physics run beside track (the next frame), so their sum is not the step's time.")]
    if res.get("tracker_in_loop"):
        t = res["tracker_in_loop"]
        lines += ["", (f"The hybrid in the as-run loop: {t['in_loop_median_ms']:.1f} ms median over {t['frames']} "
                       f"frames; replayed alone on the same frames: {t['isolated_median_ms']:.1f} ms "
                       f"({t['in_loop_over_isolated']:.2f}×).")]
    if res.get("presets"):
        p = res["presets"]
        lines += ["", "| camera preset | mean ms | × ideal |", "|---|---|---|"]
        lines += [f"| {n} | {v['rgb_ms_mean']:.1f} | {v['ratio_to_ideal']:.2f} |" for n, v in p.items()
                  if isinstance(v, dict)]
        lines += ["", f"Realistic presets: {p['realistic_mean_ratio_to_ideal']:.2f}× ideal's render cost on average."]
    t = res["trackers"]
    lines += ["", (f"Trackers on the same {res['tracker_frames']} hand-held walk_by frames: hybrid "
                   f"{t['hybrid']['median_ms']:.1f} ms median, ECC {t['ecc']['median_ms']:.2f} ms, ratio "
                   f"{t['hybrid_over_ecc']:.1f}×.")]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="experiments/results/loop_speed")
    ap.add_argument("--steps", type=int, default=240)
    ap.add_argument("--tracker-frames", type=int, default=150)
    ap.add_argument("--preset-frames", type=int, default=PRESET_FRAMES, help="0: no per-preset render costs")
    ap.add_argument("--configs", nargs="*", default=["as_run", "no_rrd", "no_eval", "pipelined"])
    ap.add_argument("--camera-pairs", type=int, default=0,
                    help="also run the loop through each of --cameras in turn this many times (0: not)")
    ap.add_argument("--cameras", nargs="+", default=["ideal", "phone_handheld"],
                    help="the cameras of --camera-pairs, the reference first; PRESET:VARIANT for bench_render's "
                         "VARIANTS (phone_handheld:sharp, phone_handheld:small)")
    ap.add_argument("--camera-config", default="no_rrd", help="the configuration of --camera-pairs' loops")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(2)
    # name: (evaluate, rrd, multisample, pipeline)
    configs = {"as_run": (True, True, None, False), "no_rrd": (True, False, None, False),
               "no_eval": (False, False, None, False), "pipelined": (True, True, None, True),
               "pipelined_no_eval": (False, False, None, True), "as_run_ms4": (True, True, 4, False),
               "no_eval_ms4": (False, False, 4, False)}
    # the machine's load beside its timings: other processes on the 2 cores slow every figure here
    res = {"machine": platform.machine(), "load_average_start": os.getloadavg()[0],
           "torch_threads": torch.get_num_threads(), "steps": args.steps,
           "tracker_frames": args.tracker_frames, "loop": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.configs:
            res["loop"][name] = loop_run(name, args.steps, *configs[name], Path(tmp))
            r = res["loop"][name]
            print(f"{name:12s} " + " ".join(f"{k} {v:.1f}" for k, v in r["mean_ms"].items())
                  + f" ms (mean) | {r['steps_per_second']:.1f} steps/s as run, {r['steps_per_second_after_first']:.1f} "
                  f"after step 0 | converged {r['converged']} {r['final_error_px']:.2f} px", flush=True)
        if args.camera_pairs:
            res["cameras"] = camera_loops(args.camera_pairs, args.steps, configs[args.camera_config],
                                          tuple(args.cameras), Path(tmp))
        if not args.configs:
            res["load_average_end"] = os.getloadavg()[0]
            (out / "speed.json").write_text(json.dumps(res, indent=2))
            print(f"written: {out}/speed.json")
            return
        res["tracker_in_loop"] = t = tracker_in_loop(args.steps, Path(tmp))
        print(f"hybrid in the loop {t['in_loop_median_ms']:.1f} ms, alone on the same frames {t['isolated_median_ms']:.1f}"
              f" ms: {t['in_loop_over_isolated']:.2f}x", flush=True)
    if args.preset_frames:
        res["presets"] = p = preset_costs(args.preset_frames)
        print("render cost: " + ", ".join(f"{n} {v['rgb_ms_mean']:.1f} ms ({v['ratio_to_ideal']:.2f}x)"
                                          for n, v in p.items() if isinstance(v, dict))
              + f"; realistic presets {p['realistic_mean_ratio_to_ideal']:.2f}x ideal", flush=True)
    res["trackers"] = tracker_timing(args.tracker_frames)
    t = res["trackers"]
    print(f"hybrid {t['hybrid']['median_ms']:.1f} ms, ecc {t['ecc']['median_ms']:.2f} ms: {t['hybrid_over_ecc']:.1f}×")
    res["load_average_end"] = os.getloadavg()[0]
    (out / "speed.json").write_text(json.dumps(res, indent=2))
    (out / "speed.md").write_text(markdown(res))
    print(f"written: {out}/speed.json, speed.md")


if __name__ == "__main__":
    main()
