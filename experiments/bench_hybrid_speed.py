"""Speed of the hybrid tracker per 640×480 frame against ECC, on the same frames in one process.

    python experiments/bench_hybrid_speed.py --json experiments/results/hybrid_speed.json

Renders the hand-held sequences as bench_tracking_core.py does (default camera; walk_by, pause and
partial, seed 100), then runs the hybrid with the similarity warp, the hybrid with the homography
warp, both again with the alignment before the leaner LK (`hybrid_full_lk`), and ECC
(make_tracker("ecc")) with torch.set_num_threads(2). The trackers take turns frame by
frame (the order rotating), so a change of machine load hits all of them alike; the figure to
compare across runs is therefore the ratio hybrid / ECC, printed beside the milliseconds. Prints and
writes median / p95 ms per frame of each, that ratio, the hybrid's median error (a sanity check, not
the accuracy benchmark: see bench_tracking_core.py) and the hybrid's mean ms per stage
(HybridTracker.stage_ms: per frame, stages that did not run count 0). The load average at start and
end is recorded: on a machine whose two cores are shared, torch's two threads meet at a barrier in
every parallel region and wait for a time slice there, so the hybrid slows far more than ECC does.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

from hvs_sim.bench.sequences import make_sequence
from hvs_sim.scene.scenarios import make_scenario
from hvs_sim.tracking import make_tracker

TRACKERS = {  # label → (make_tracker name, settings)
    "hybrid_similarity": ("hybrid", {"warp": "similarity"}),
    "hybrid_homography": ("hybrid", {"warp": "homography"}),
    # the alignment before the leaner LK (registry: hybrid_full_lk), timed beside it
    "full_lk_similarity": ("hybrid_full_lk", {"warp": "similarity"}),
    "full_lk_homography": ("hybrid_full_lk", {"warp": "homography"}),
    # each frame's surroundings from the frame five back alone (registry: hybrid_interleaved_hops), not also four back
    "interleaved_hops": ("hybrid_interleaved_hops", {"warp": "similarity"}),
    "ecc": ("ecc", {}),
}


def run(sequences, labels: list[str]) -> dict:
    per = {lb: {"ms": [], "err": [], "stages": [], "aligned": []} for lb in labels}
    for seq in sequences:
        trackers = {}
        for lb in labels:
            name, cfg = TRACKERS[lb]
            trackers[lb] = make_tracker(name, **cfg)
            trackers[lb].init(seq.frames[0], seq.roi)
        gt = seq.gt_track
        for k in range(1, len(seq.frames)):
            order = labels[k % len(labels):] + labels[:k % len(labels)]  # rotate who goes first
            for lb in order:
                tr = trackers[lb]
                tk = tr.update(seq.frames[k])
                per[lb]["ms"].append(tk.ms)
                per[lb]["err"].append(float(np.linalg.norm(tk.center - gt[k])))
                per[lb]["aligned"].append(tk.mode == "align")
                if hasattr(tr, "stage_ms"):
                    per[lb]["stages"].append(dict(tr.stage_ms))
    return per


def summary(per: dict, ecc_label: str = "ecc") -> dict:
    out = {}
    ecc_median = float(np.median(per[ecc_label]["ms"])) if ecc_label in per else None
    for lb, d in per.items():
        ms = np.array(d["ms"])
        aligned = np.array(d["aligned"], bool)
        s = {"frames": int(ms.size), "median_ms": float(np.median(ms)), "p95_ms": float(np.percentile(ms, 95)),
             "mean_ms": float(ms.mean()), "median_px": float(np.median(d["err"])),
             # the two paths cost differently (align: VGG + LK; otherwise the motion sources): the
             # median over all frames depends on how many frames of each the sequences have
             "aligned_frames": int(aligned.sum()),
             "median_ms_aligned": float(np.median(ms[aligned])) if aligned.any() else None,
             "median_ms_not_aligned": float(np.median(ms[~aligned])) if (~aligned).any() else None}
        if ecc_median and lb != ecc_label:
            s["ratio_to_ecc"] = s["median_ms"] / ecc_median
        if d["stages"]:
            names = dict.fromkeys(st for frame in d["stages"] for st in frame)  # in order of appearance
            s["stage_mean_ms"] = {st: float(np.mean([frame.get(st, 0.0) for frame in d["stages"]])) for st in names}
        out[lb] = s
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", nargs="+", default=["walk_by", "pause", "partial"])
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--frames", type=int, default=None, help="frames per sequence (default: the scenario's length)")
    ap.add_argument("--trackers", nargs="+", default=list(TRACKERS), choices=list(TRACKERS))
    ap.add_argument("--json", default="experiments/results/hybrid_speed.json")
    args = ap.parse_args()
    torch.set_num_threads(2)
    t0 = time.perf_counter()
    sequences = [make_sequence(make_scenario(s, mount="handheld", seed=args.seed), n_frames=args.frames)
                 for s in args.scenarios]
    render_s = time.perf_counter() - t0
    load_start = os.getloadavg()
    labels = args.trackers if "ecc" in args.trackers else [*args.trackers, "ecc"]
    res = summary(run(sequences, labels))
    load_end = os.getloadavg()
    out = {"machine": platform.machine(), "processor": platform.processor(), "cpus": os.cpu_count(),
           "torch_threads": torch.get_num_threads(), "torch": torch.__version__, "scenarios": args.scenarios,
           "seed": args.seed, "load_average_start": load_start, "load_average_end": load_end,
           "render_s": render_s, "track_s": time.perf_counter() - t0 - render_s, "results": res}
    for lb, s in res.items():
        ratio = f" = {s['ratio_to_ecc']:.1f}× ECC" if "ratio_to_ecc" in s else ""
        stages = "  ".join(f"{k} {v:.2f}" for k, v in s.get("stage_mean_ms", {}).items())
        paths = "  ".join(f"{nm} {s[key]:.2f}" for nm, key in (("aligned", "median_ms_aligned"),
                                                                 ("not aligned", "median_ms_not_aligned")) if s[key])
        print(f"{lb:18s} median {s['median_ms']:6.2f} ms{ratio:12s} p95 {s['p95_ms']:6.2f} ms  median err "
              f"{s['median_px']:.3f} px" + (f"\n{'':18s} median ms per frame: {paths}" if paths else "")
              + (f"\n{'':18s} mean ms per stage: {stages}" if stages else ""))
    print(f"load average {load_start[0]:.1f} → {load_end[0]:.1f} (1 min; {os.cpu_count()} CPUs)")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
