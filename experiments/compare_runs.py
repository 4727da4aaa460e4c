"""Side-by-side tables of benchmark runs (tracking target set, or servo success), one column per run.

    python experiments/compare_runs.py track experiments/results/archive/track experiments/results/archive/track_ideal \
        experiments/results/track_phone_handheld --labels "plain, ideal" "textured, ideal" "textured, phone_handheld"
    python experiments/compare_runs.py servo experiments/results/servo_ideal experiments/results/servo_phone_handheld

Prints markdown; the README's comparison tables come from here.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

TARGET_SCENARIOS = ("walk_by", "pause", "partial")


def _load(run: str) -> dict:
    return json.loads((Path(run) / "summary.json").read_text())


def track_table(runs: list[str], labels: list[str]) -> str:
    """Target-set ≤ 2 px (all frames / frames with occlusion < 40 %) and median px per method and run."""
    summaries = [_load(r)["target_set"] for r in runs]
    methods = [m for m in summaries[0] if all(m in s for s in summaries)]
    head = "| method | " + " | ".join(labels) + " |"
    lines = [head, "|---|" + "---|" * len(labels)]
    for m in methods:
        cells = [f"{s[m]['all']['pct_le_2px']:.1f} % / {s[m]['visible_lt_40']['pct_le_2px']:.1f} % / "
                 f"{s[m]['all']['median_px']:.2f}" for s in summaries]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    per = [_hybrid_per_scenario(r) for r in runs]
    lines += ["", "hybrid ≤ 2 px per scenario of the target set (hand-held):", "",
              "| scenario | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    for scen in TARGET_SCENARIOS:
        lines.append(f"| {scen} | " + " | ".join(f"{p[scen]:.1f} %" for p in per) + " |")
    return "\n".join(lines)


def _hybrid_per_scenario(run: str) -> dict[str, float]:
    """Share of hand-held frames ≤ 2 px per target-set scenario, from frames.csv (init frames left out)."""
    ok: dict[str, list[bool]] = {s: [] for s in TARGET_SCENARIOS}
    with open(Path(run) / "frames.csv", newline="") as f:
        for row in csv.DictReader(f):
            if row["method"] == "hybrid" and row["mount"] == "handheld" and row["scenario"] in ok and row["frame"] != "0":
                ok[row["scenario"]].append(float(row["error_px"]) <= 2.0)
    return {s: 100.0 * sum(v) / max(1, len(v)) for s, v in ok.items()}


def servo_table(runs: list[str], labels: list[str]) -> str:
    """Success rate and median final error per scenario and tracker, one column per run."""
    results = [_load(r)["results"] for r in runs]
    lines = ["| scenario | tracker | " + " | ".join(labels) + " |", "|---|---|" + "---|" * len(labels)]
    for scen, per in results[0].items():
        for t in per:
            cells = [f"{100 * r[scen][t]['success_rate']:.0f} % / {r[scen][t]['median_final_error_px']:.2f} px"
                     if t in r.get(scen, {}) else "–" for r in results]
            lines.append(f"| {scen} | {t} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("kind", choices=("track", "servo"))
    ap.add_argument("runs", nargs="+", help="benchmark output folders (each with summary.json)")
    ap.add_argument("--labels", nargs="+", default=None, help="column titles (default: folder names)")
    args = ap.parse_args()
    labels = args.labels or [Path(r).name for r in args.runs]
    if len(labels) != len(args.runs):
        ap.error(f"give one label per run ({len(args.runs)}), got {len(labels)}")
    for r in args.runs:
        if not (Path(r) / "summary.json").is_file():
            ap.error(f"{r} has no summary.json")
    print(track_table(args.runs, labels) if args.kind == "track" else servo_table(args.runs, labels))


if __name__ == "__main__":
    main()
