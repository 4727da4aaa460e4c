"""What the init check's trackability predicts: many ROIs (random places and sizes; on each sequence the least textured of 60 drawn and some at random) on the natural
benchmark's hand-held `clear` sequences, each tracked by the hybrid with every template accepted
(`allow_untrackable=True`), binned by the template's weakest-direction texture (texture_measure.structure, noise
taken out) and by the verdict tracking/trackability.py gives it (ok / weak / flat / one direction).

    python experiments/trackability_study.py --out experiments/results/trackability

Prints, per bin and per verdict, the number of ROIs and the share of their frames within 2 px; writes
summary.json (atomically). Ground truth: the sequences' homographies carry any frame-0 point to every frame.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hvs_sim.bench.natural import NATURAL_SOURCES, make_natural_sequence
from hvs_sim.bench.splits import check_tuning_seeds
from hvs_sim.outputs import write_atomic
from hvs_sim.texture_measure import structure
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.trackability import EDGE_RATIO, FLAT_SIGNAL, MIN_TRACKABILITY

FRAMES = 60
ROIS_PER_SEQUENCE = 8
CANDIDATES = 60  # random ROIs drawn per sequence; the LEAST least textured are always studied, the rest at random
LEAST = 4
BINS = (0.0, 1e-7, 1e-6, MIN_TRACKABILITY, 2e-5, 1e-4, np.inf)  # weakest-direction texture, noise taken out


def verdict(weakest: float, strongest: float) -> str:
    if weakest >= MIN_TRACKABILITY:
        return "ok"
    if strongest < FLAT_SIGNAL:
        return "flat"
    return "one direction" if weakest < EDGE_RATIO * strongest else "weak"


def centre_track(seq, roi) -> np.ndarray:
    """The true image position of a frame-0 ROI's centre in every frame (through the picture's homographies)."""
    x, y, w, h = roi
    c0 = np.array([x + (w - 1) / 2, y + (h - 1) / 2, 1.0])
    on_picture = np.linalg.solve(seq.homographies[0], c0)
    p = seq.homographies @ on_picture
    return p[:, :2] / p[:, 2:]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="experiments/results/trackability")
    ap.add_argument("--seeds", type=int, nargs="+", default=[700])
    ap.add_argument("--allow-test-seeds", action="store_true",
                    help="allow track test seeds (bench/splits.py), which figures are published on; recorded")
    args = ap.parse_args()
    check_tuning_seeds("track", args.seeds, args.allow_test_seeds)  # tuning looks at dev seeds only
    t0 = time.time()
    rows = []
    jobs = [(s, seed) for s in NATURAL_SOURCES for seed in args.seeds]
    for source, seed in tqdm(jobs, desc="trackability", unit="seq"):
        seq = make_natural_sequence(source, "clear", seed, n_frames=FRAMES, camera="phone_handheld")
        rng = np.random.default_rng([seed, len(rows)])
        h_img, w_img = seq.frames.shape[1:3]
        candidates = []
        for _ in range(CANDIDATES):
            w = int(rng.integers(48, 161))
            h = round(w * rng.uniform(0.6, 1.0))
            x, y = int(rng.integers(40, w_img - w - 40)), int(rng.integers(40, h_img - h - 40))
            candidates.append((structure(seq.frames[0][y:y + h, x:x + w])[0], (x, y, w, h)))
        candidates.sort(key=lambda c: c[0])  # the least textured first: the low bins are what the study is about
        rest = [candidates[k] for k in rng.permutation(np.arange(LEAST, len(candidates)))[:ROIS_PER_SEQUENCE - LEAST]]
        for _, (x, y, w, h) in candidates[:LEAST] + rest:
            tracker = make_tracker("hybrid", allow_untrackable=True)
            tracker.init(seq.frames[0], (x, y, w, h))
            weakest, strongest = structure(tracker.aligner.template)
            truth = centre_track(seq, (x, y, w, h))
            err = [float(np.hypot(*(tracker.update(f).center - truth[k]))) for k, f in enumerate(seq.frames[1:], 1)]
            rows.append({"sequence": seq.name, "roi": [x, y, w, h], "weakest": weakest, "strongest": strongest,
                         "verdict": verdict(weakest, strongest), "within_2px": float(np.mean(np.array(err) <= 2)),
                         "max_px": max(err)})
    table = {"bins": [], "verdicts": {}}
    print("| weakest-direction texture | ROIs | frames within 2 px (mean over ROIs) | ROIs with every frame within 2 px |\n"
          "|---|---|---|---|")
    for lo, hi in itertools.pairwise(BINS):
        mine = [r for r in rows if lo <= r["weakest"] < hi]
        share = float(np.mean([r["within_2px"] for r in mine])) if mine else None
        whole = sum(r["within_2px"] == 1.0 for r in mine)
        table["bins"].append({"from": lo, "to": None if np.isinf(hi) else hi, "rois": len(mine),
                              "within_2px": share, "all_frames_within_2px": whole})
        print(f"| {lo:.0e} – {hi:.0e} | {len(mine)} | {'n/a' if share is None else f'{share:.1%}'} | {whole} |")
    print("\n| verdict | ROIs | frames within 2 px | ROIs with every frame within 2 px |\n|---|---|---|---|")
    for v in ("ok", "weak", "one direction", "flat"):
        mine = [r for r in rows if r["verdict"] == v]
        share = float(np.mean([r["within_2px"] for r in mine])) if mine else None
        whole = sum(r["within_2px"] == 1.0 for r in mine)
        table["verdicts"][v] = {"rois": len(mine), "within_2px": share, "all_frames_within_2px": whole}
        print(f"| {v} | {len(mine)} | {'n/a' if share is None else f'{share:.1%}'} | {whole} |")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "summary.json", json.dumps({"allow_test_seeds": args.allow_test_seeds, "command": " ".join(["python", *sys.argv]), "frames": FRAMES,
                                                   "seconds": time.time() - t0, "table": table, "rois": rows},
                                                  indent=1))
    print(f"summary: {out / 'summary.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
