"""Closed-loop speed: per-stage ms and steps/s of the demo run, with and without evaluation, and the
hybrid's ms beside the ECC baseline's on the same frames in the same process.

    python experiments/bench_loop.py --out experiments/results/loop_speed

Writes speed.json and speed.md there (the README's *Loop speed* table comes from speed.md). Run it
on a quiet machine: the steps/s are absolute figures of this machine; the hybrid/ECC ratio is what
carries across machines.

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
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from hvs_sim.bench.sequences import make_sequence
from hvs_sim.bench.track import run_tracker
from hvs_sim.loop import LoopConfig
from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import make_scenario

STAGES = ("render", "ground_truth", "track", "control", "physics", "log")


def loop_run(name: str, steps: int, evaluate: bool, rrd: bool, multisample: int | None, pipeline: bool, tmp: Path) -> dict:
    base = make_scenario("walk_by", mount="arm", seed=0)
    scen = base if multisample is None else dataclasses.replace(
        base, camera=dataclasses.replace(base.camera, multisample=multisample))
    cfg = LoopConfig(steps=steps, evaluate=evaluate, keep_frames=rrd, pipeline=pipeline)
    t0 = time.perf_counter()
    summary, _ = run_episode(scen, "hybrid", cfg, rrd=str(tmp / f"{name}.rrd") if rrd else None,
                             json_path=str(tmp / f"{name}.json"), progress=False)
    wall = time.perf_counter() - t0
    stages = {k: summary["timing"][k]["median_ms"] for k in STAGES if k in summary["timing"]}
    means = {k: summary["timing"][k]["mean_ms"] for k in STAGES if k in summary["timing"]}
    return {"evaluate": evaluate, "rrd": rrd, "multisample": scen.camera.multisample, "pipeline": pipeline,
            "median_ms": stages,
            "mean_ms": means, "steps_per_second": summary["steps_per_second"],
            "wall_seconds_with_setup": wall, "converged": summary["converged"],
            "final_error_px": summary["final_error_px"]}


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
    lines = ["| configuration | " + " | ".join(STAGES) + " | steps/s | converged | final px |",
             "|---" * (len(STAGES) + 4) + "|"]
    for name, r in res["loop"].items():
        cells = [f"{r['median_ms'][k]:.1f}" if k in r["median_ms"] else "—" for k in STAGES]
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {r['steps_per_second']:.1f} | {r['converged']} | "
                     f"{r['final_error_px']:.2f} |")
    lines += ["", ("Pipelined: render, ground truth and physics run beside track (the next frame), so their sum is not "
                   "the step's time; steps/s is from the wall time.")]
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
    ap.add_argument("--configs", nargs="+", default=["as_run", "no_eval", "pipelined", "pipelined_no_eval", "as_run_ms4"])
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(2)
    # name: (evaluate, rrd, multisample, pipeline)
    configs = {"as_run": (True, True, None, False), "no_eval": (False, False, None, False),
               "pipelined": (True, True, None, True), "pipelined_no_eval": (False, False, None, True),
               "as_run_ms4": (True, True, 4, False), "no_eval_ms4": (False, False, 4, False)}
    res = {"machine": platform.machine(), "torch_threads": torch.get_num_threads(), "steps": args.steps,
           "tracker_frames": args.tracker_frames, "loop": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.configs:
            res["loop"][name] = loop_run(name, args.steps, *configs[name], Path(tmp))
            r = res["loop"][name]
            print(f"{name:12s} " + " ".join(f"{k} {v:.1f}" for k, v in r["median_ms"].items())
                  + f" ms | {r['steps_per_second']:.1f} steps/s | converged {r['converged']} "
                  f"{r['final_error_px']:.2f} px", flush=True)
    res["trackers"] = tracker_timing(args.tracker_frames)
    t = res["trackers"]
    print(f"hybrid {t['hybrid']['median_ms']:.1f} ms, ecc {t['ecc']['median_ms']:.2f} ms: {t['hybrid_over_ecc']:.1f}×")
    (out / "speed.json").write_text(json.dumps(res, indent=2))
    (out / "speed.md").write_text(markdown(res))
    print(f"written: {out}/speed.json, speed.md")


if __name__ == "__main__":
    main()
