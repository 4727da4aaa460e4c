"""Resident memory of a long closed-loop run: flat in the number of steps?

    python experiments/bench_memory.py --steps 100000 --tracker ground_truth --width 160 --height 120 --no-eval \
        --json experiments/results/memory/gt_100k.json
    python experiments/bench_memory.py --steps 10000 --tracker hybrid --json experiments/results/memory/hybrid_10k.json

Runs one episode through hvs_sim.runner.run_episode (JSON + per-step CSV written as it goes; `--rrd` adds a
recording) and samples the process's resident set size (VmRSS) every `--every` steps. Reports the RSS
after the first `--every` steps (set-up, GL context, weights, first allocations done) and at the end,
and their difference: the growth the run's length causes. The JSON is rewritten at every sample, so a
run stopped early keeps what it measured (`finished`: false, `steps_sampled`).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.records import RunStats


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status (Linux only)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=100_000)
    ap.add_argument("--every", type=int, default=1000)
    ap.add_argument("--tracker", default="ground_truth")
    ap.add_argument("--scenario", default="walk_by")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--no-eval", action="store_true")
    ap.add_argument("--rrd", action="store_true", help="also record an .rrd (beside the JSON)")
    ap.add_argument("--json", default="experiments/results/memory/memory.json")
    args = ap.parse_args()
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    samples: list[tuple[int, float, float]] = []
    add, t0 = RunStats.add, time.perf_counter()

    def sampled(self, r):  # RunStats.add runs once a step inside run_episode: sample there
        add(self, r)
        if self.n % args.every == 0:
            samples.append((self.n, rss_mb(), time.perf_counter() - t0))
            write(None)  # as it goes: a run stopped early (Ctrl-C, SIGTERM, a time limit) keeps its samples

    def write(summary: dict | None) -> None:
        first, last = samples[0], samples[-1]
        finished = summary is not None and not summary.get("interrupted", False)
        res = {"steps": args.steps, "steps_sampled": last[0], "finished": finished, "tracker": args.tracker,
               "size": [args.width, args.height], "evaluate": not args.no_eval, "rrd": args.rrd,
               "rss_mb_after_first": first[1], "rss_mb_at_end": last[1], "growth_mb": last[1] - first[1],
               "max_rss_mb": max(s[1] for s in samples),
               "steps_per_second": summary["steps_per_second"] if summary else last[0] / last[2],
               "samples": [{"step": n, "rss_mb": m, "seconds": s} for n, m, s in samples]}
        tmp = out.with_name(out.name + ".tmp")  # written whole, then renamed: a kill mid-write leaves the last one
        tmp.write_text(json.dumps(res, indent=2))
        tmp.replace(out)

    RunStats.add = sampled
    scen = make_scenario(args.scenario, mount="arm", seed=0, camera=CameraConfig(width=args.width, height=args.height))
    cfg = LoopConfig(steps=args.steps, evaluate=not args.no_eval, keep_frames=args.rrd)
    summary, _ = run_episode(scen, args.tracker, cfg, progress=True, json_path=str(out.with_name(out.stem + "_run.json")),
                             rrd=str(out.with_suffix(".rrd")) if args.rrd else None)
    if not samples:
        raise SystemExit(f"the run ended before step {args.every}: no memory sample taken")
    write(summary)
    first, last = samples[0], samples[-1]
    print(f"{last[0]} steps: RSS {first[1]:.1f} MB after {first[0]} steps, {last[1]:.1f} MB at the end "
          f"(growth {last[1] - first[1]:+.1f} MB); written {out}")


if __name__ == "__main__":
    main()
