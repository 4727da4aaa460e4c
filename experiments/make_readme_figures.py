"""Figures for the README: frames of a closed-loop hybrid run through walk_by with overlays
(tracked corners green, true corners white, desired corners red), and its error/occlusion plot.

    python experiments/make_readme_figures.py --out experiments/results/figures
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import make_scenario
from hvs_sim.servo.config import LoopConfig


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="experiments/results/figures")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary, _ = run_episode(make_scenario("walk_by", mount="arm", seed=0), "hybrid", LoopConfig(steps=240), figures=out)
    frames, error = (Path(p) for p in summary["figures"])
    frames.replace(out / "run_walk_by_hybrid_frames.png")
    error.replace(out / "run_walk_by_hybrid_error.png")
    print(summary)


if __name__ == "__main__":
    main()
