"""Trackers on the footage cases of hvs_sim/bench/footage.py: a target that moves on its own over a still scene, and
a scene cut to a shot without the target.

    python experiments/bench_footage.py --out experiments/results/footage

Prints, per tracker and case kind: the share of frames with the target in view tracked within 2 px, the median
error, how many frames after the cut the tracker first said `lost` (and the share of after-cut frames it said so),
what `auto` chose, and the median update time beside ECC's measured in the same run (as a ratio). Writes
summary.json (atomically).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hvs_sim.bench.footage import moving_object, scene_cut
from hvs_sim.outputs import write_atomic
from hvs_sim.tracking import make_tracker

TRACKERS = ("hybrid", "hybrid_auto_motion", "hybrid_moving", "ecc", "deep_lk")
CASES = {"moving_object": moving_object, "scene_cut": scene_cut}
FPS = 30.0


def run_case(case, name: str) -> dict:
    tracker = make_tracker(name)
    tracker.init(case.frames[0], case.roi)
    errors, modes, ms = [], [], []
    for k, frame in enumerate(case.frames[1:], 1):
        track = tracker.update(frame)
        modes.append(str(track.mode))
        ms.append(track.ms)
        c = case.centres[k]
        errors.append(float(np.hypot(*(track.center - c))) if np.isfinite(c).all() else None)
    out = {"case": case.name, "tracker": name, "errors": errors, "modes": modes, "median_ms": statistics.median(ms),
           "notes": list(getattr(tracker, "notes", []))}
    if case.cut_at is not None:
        after = modes[case.cut_at - 1:]
        out["frames_to_lost"] = after.index("lost") if "lost" in after else None
        out["lost_share_after_cut"] = after.count("lost") / len(after)
    return out


def summarise(rows: list[dict]) -> dict:
    table: dict = {}
    for kind in CASES:
        for name in TRACKERS:
            mine = [r for r in rows if r["tracker"] == name and r["case"].startswith(kind)]
            err = np.array([e for r in mine for e in r["errors"] if e is not None])
            entry = {"sequences": len(mine), "frames_with_target": int(err.size),
                     "within_2px": float((err <= 2).mean()) if err.size else None,
                     "median_px": float(np.median(err)) if err.size else None,
                     "median_ms": statistics.median(r["median_ms"] for r in mine)}
            if kind == "scene_cut":
                lost = [r["frames_to_lost"] for r in mine]
                entry["cuts_ending_in_lost"] = sum(v is not None for v in lost)
                entry["worst_frames_to_lost"] = None if None in lost else max(lost)
                entry["lost_share_after_cut"] = statistics.mean(r["lost_share_after_cut"] for r in mine)
            if name == "hybrid_auto_motion":
                entry["auto_chose"] = {r["case"]: next((n.split(" at frame")[0].split()[-1] for n in r["notes"]
                                                        if n.startswith("target motion")), "undecided") for r in mine}
            table.setdefault(kind, {})[name] = entry
    return table


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="experiments/results/footage")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(6)))
    args = ap.parse_args()
    rows = []
    t0 = time.time()
    with tqdm(total=len(CASES) * len(args.seeds) * len(TRACKERS), desc="footage", unit="run") as bar:
        for make in CASES.values():
            for seed in args.seeds:
                case = make(seed)  # made once, run by every tracker
                for name in TRACKERS:
                    rows.append(run_case(case, name))
                    bar.update(1)
    table = summarise(rows)
    ecc_ms = {kind: table[kind]["ecc"]["median_ms"] for kind in CASES}
    print("| case | tracker | frames with target | ≤ 2 px | median px | cut → lost (worst frames; after-cut lost) "
          "| median ms | × ECC |\n|---|---|---|---|---|---|---|---|")
    for kind, per in table.items():
        for name, e in per.items():
            cut = (f"{e['cuts_ending_in_lost']}/{e['sequences']} ({e['worst_frames_to_lost']}; "
                   f"{e['lost_share_after_cut']:.0%})" if kind == "scene_cut" else "")
            within = f"{e['within_2px']:.1%}" if e["within_2px"] is not None else "n/a"
            print(f"| {kind} | {name} | {e['frames_with_target']} | {within} | {e['median_px']:.2f} | {cut} | "
                  f"{e['median_ms']:.1f} | {e['median_ms'] / ecc_ms[kind]:.1f} |")
    for kind in CASES:
        print(f"auto chose ({kind}): {table[kind]['hybrid_auto_motion']['auto_chose']}")
    write_summary(args.out, t0, table, rows, seeds=args.seeds)
    return 0


def write_summary(out: str, t0: float, table: dict, rows: list[dict], **extra) -> Path:
    """summary.json in `out` (made if missing), written atomically: the command, what `extra` names, the run's
    seconds since `t0`, the table and every run."""
    path = Path(out) / "summary.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps({"command": " ".join(["python", *sys.argv]), **extra, "seconds": time.time() - t0,
                                   "table": table, "runs": rows}, indent=1))
    print(f"summary: {path}")
    return path


if __name__ == "__main__":
    sys.exit(main())
