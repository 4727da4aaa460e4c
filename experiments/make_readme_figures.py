"""Figures for the README: frames of a closed-loop hybrid run through walk_by with overlays
(tracked corners green, true corners white, desired corners red), and its error/occlusion plot.

    python experiments/make_readme_figures.py --out experiments/results/figures
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hvs_sim.loop import LoopConfig
from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import make_scenario


def overlay(r) -> np.ndarray:
    img = cv2.cvtColor(r.frame, cv2.COLOR_RGB2BGR)
    for pts, col in ((r.desired, (60, 60, 255)), (r.gt_features, (255, 255, 255)), (r.features, (0, 255, 0))):
        if np.all(np.isfinite(pts)):
            cv2.polylines(img, [np.round(pts * 16).astype(np.int32)], True, col, 2, cv2.LINE_AA, shift=4)
    img = cv2.resize(img, (480, 360), interpolation=cv2.INTER_AREA)
    label = f"t={r.time:.2f}s {r.mode} occl. {r.occlusion:.0%} err {r.error_px:.2f}px"
    cv2.rectangle(img, (0, 0), (480, 30), (0, 0, 0), -1)
    cv2.putText(img, label, (8, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="experiments/results/figures")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary, recs = run_episode(make_scenario("walk_by", mount="arm", seed=0), "hybrid", LoopConfig(steps=240),
                                keep_records=True)
    occ = np.array([r.occlusion for r in recs])
    picks = [0, int(np.argmax(occ > 0.3)), int(np.argmax(occ)), len(recs) - 1]
    tiles = [overlay(recs[i]) for i in picks]
    cv2.imwrite(str(out / "run_walk_by_hybrid_frames.png"), np.vstack([np.hstack(tiles[:2]), np.hstack(tiles[2:])]))
    t = np.array([r.time for r in recs])
    fig, ax = plt.subplots(figsize=(9, 3.4))
    ax.semilogy(t, [r.error_px for r in recs], color="tab:red", label="ground-truth error to s* (px)")
    ax.semilogy(t, [max(r.tracker_error_px, 1e-3) for r in recs], color="tab:green", label="tracker corner error (px)")
    ax.axhline(0.5, ls="--", color="k", lw=0.8)
    pred = np.array([r.mode == "predict" for r in recs])
    ax.fill_between(t, 1e-3, 1e3, where=pred, color="tab:blue", alpha=0.15, step="mid", label="GRU predicts")
    tw = ax.twinx()
    tw.fill_between(t, 0, 100 * occ, color="grey", alpha=0.3, step="mid")
    tw.set_ylabel("true occlusion (%)")
    tw.set_ylim(0, 100)
    ax.set_ylim(1e-2, 1e2)
    ax.set_xlabel("time (s)")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title(f"hvs-sim run --scenario walk_by --tracker hybrid: final error {summary['final_error_px']:.2f} px")
    fig.tight_layout()
    fig.savefig(out / "run_walk_by_hybrid_error.png", dpi=100)
    print(summary)


if __name__ == "__main__":
    main()
