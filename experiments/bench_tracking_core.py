"""Tracker-core benchmark: sift, ecc, deep_lk on the hand-held `clear` and `walk_by` sequences.

    python experiments/bench_tracking_core.py --seeds 100 101 --json experiments/results/tracking_core.json

Prints % frames ≤ 1 px and ≤ 2 px, median/p95 error and median/p95 ms per frame for each method,
over all frames and over unoccluded frames (true occlusion 0), then over all the scenarios together.
Single process: the quiet timing run (the tracking benchmark's ms come from two workers sharing the cores).

    python experiments/bench_tracking_core.py --methods hybrid --scenarios walk_by pause partial \
        --seeds 100 101 102 --json experiments/results/archive/hybrid_timing.json

With `--imagery natural` the sequences are hvs_sim.bench.natural's (pictures moved like a hand-held phone,
through the phone_handheld camera): `--scenarios` are its kinds and `--sources` its pictures.
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

import torch

from hvs_sim.bench.sequences import make_sequence
from hvs_sim.bench.splits import check_tuning_seeds
from hvs_sim.bench.track import run_tracker, summarize
from hvs_sim.scene.scenarios import make_scenario


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--methods", nargs="+", default=["sift", "ecc", "deep_lk"])
    ap.add_argument("--scenarios", nargs="+", default=["clear", "walk_by"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[100, 101])
    ap.add_argument("--json", default="experiments/results/tracking_core.json")
    ap.add_argument("--imagery", choices=("sim", "natural"), default="sim")
    ap.add_argument("--sources", nargs="+", default=None, help="natural imagery: pictures (default all)")
    ap.add_argument("--allow-test-seeds", action="store_true",
                    help="allow track test seeds (bench/splits.py), which figures are published on; recorded")
    args = ap.parse_args()
    check_tuning_seeds("track", args.seeds, args.allow_test_seeds)  # tuning looks at dev seeds only
    if args.imagery == "natural":
        from hvs_sim.bench.natural import NATURAL_SOURCES, make_natural_sequence

        sources = args.sources or list(NATURAL_SOURCES)

        def sequences(scen):
            return [make_natural_sequence(src, scen, s) for src in sources for s in args.seeds]
    else:
        def sequences(scen):
            return [make_sequence(make_scenario(scen, mount="handheld", seed=s), progress=True) for s in args.seeds]
    torch.set_num_threads(2)
    out = {"machine": platform.machine(), "torch_threads": torch.get_num_threads(), "seeds": args.seeds,
           "imagery": args.imagery, "sources": args.sources, "results": {}}
    pooled = {m: [] for m in args.methods}
    for scen in args.scenarios:
        seqs = sequences(scen)
        for method in args.methods:
            res = [run_tracker(method, q) for q in seqs]
            pooled[method] += res
            allf = summarize(res)
            clear = summarize(res, lambda r: r["occlusion"] == 0.0)
            out["results"][f"{scen}/{method}"] = {"all": allf, "unoccluded": clear}
            print(f"{scen:8s} {method:8s} all: {allf['pct_le_1px']:5.1f}% ≤1px {allf['pct_le_2px']:5.1f}% ≤2px "
                  f"median {allf['median_px']:.3f} p95 {allf['p95_px']:.2f} px | unoccluded ≤1px {clear['pct_le_1px']:5.1f}% "
                  f"≤2px {clear['pct_le_2px']:5.1f}% | {allf['median_ms']:.1f} / {allf['p95_ms']:.1f} ms (median/p95)", flush=True)
    for method, res in pooled.items():  # every frame of every sequence above
        allf = summarize(res)
        out["results"][f"all/{method}"] = {"all": allf}
        print(f"all      {method:8s} {allf['pct_le_2px']:5.1f}% ≤2px | {allf['median_ms']:.1f} / {allf['p95_ms']:.1f} ms "
              f"(median/p95)", flush=True)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps({**out, "allow_test_seeds": args.allow_test_seeds}, indent=2))


if __name__ == "__main__":
    main()
