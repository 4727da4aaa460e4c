"""Sweep engines on this machine: one spec run by the local pool with 1 and 2 workers and by Ray with 2
CPUs; wall time, speed-up, Ray's per-task overhead against the local pool, and whether the three
result tables agree (timing columns aside).

    python experiments/sweep_scaling.py --json experiments/results/sweep_scaling.json
"""

from __future__ import annotations

import argparse
import csv
import json
import tempfile
import time
from pathlib import Path

from hvs_sim.sweep import TIMING_METRICS, parse_spec, run_sweep

SPEC = """
kind = "track"
[axes]
tracker = ["ecc", "deep_lk"]
seed = [100, 101, 102, 103]
[fixed]
scenario = "walk_by"
camera = "ideal"
frames = 30
"""


def table(out: Path) -> list[dict]:
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    return sorted(({k: v for k, v in r.items() if k not in (*TIMING_METRICS, "engine")} for r in rows),
                  key=lambda r: r["id"])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default="experiments/results/sweep_scaling.json")
    args = ap.parse_args()
    spec = parse_spec(SPEC)
    n = len(spec.tasks())
    runs, tables = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for label, engine, workers in (("local, 1 worker", "local", 1), ("local, 2 workers", "local", 2),
                                       ("ray, 2 CPUs", "ray", 2)):
            out = Path(tmp) / label.replace(", ", "_").replace(" ", "")
            t0 = time.perf_counter()
            run_sweep(spec, out, engine=engine, workers=workers, progress=False)
            wall = time.perf_counter() - t0
            tasks = [json.loads(p.read_text()) for p in (out / "tasks").glob("*.json")]
            runs[label] = {"wall_s": round(wall, 2), "tasks": n, "s_per_task": round(wall / n, 3),
                           "mean_task_seconds": round(sum(t["task_seconds"] for t in tasks) / n, 3)}
            tables[label] = table(out)
            print(f"{label:18s} {wall:7.1f} s wall, {wall / n:.2f} s per task", flush=True)
    base = runs["local, 1 worker"]["wall_s"]
    for r in runs.values():
        r["speedup_vs_local_1"] = round(base / r["wall_s"], 2)
    overhead_ms = 1e3 * (runs["ray, 2 CPUs"]["wall_s"] - runs["local, 2 workers"]["wall_s"]) / n
    same = tables["local, 1 worker"] == tables["local, 2 workers"] == tables["ray, 2 CPUs"]
    result = {"spec": SPEC, "runs": runs, "ray_overhead_ms_per_task_vs_local_pool": round(overhead_ms, 1),
              "ray_overhead_note": "includes starting and stopping the local Ray instance, spread over the tasks",
              "identical_metrics_across_engines": same}
    print(json.dumps(result, indent=2))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
