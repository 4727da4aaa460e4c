"""Tracking benchmark: run trackers over rendered sequences, per-frame error, summary figures."""

from __future__ import annotations

import numpy as np

from hvs_sim.bench.sequences import Sequence
from hvs_sim.tracking import make_tracker


def run_tracker(name: str, seq: Sequence, **config) -> dict[str, np.ndarray]:
    """Per-frame arrays: error (px), ms, mode, occlusion estimate, score (frame 0 is the init frame)."""
    tracker = make_tracker(name, **config)
    tracker.init(seq.frames[0], seq.roi)
    gt = seq.gt_track
    err, ms, mode, occ_est = [0.0], [0.0], ["init"], [0.0]
    for k in range(1, len(seq.frames)):
        tk = tracker.update(seq.frames[k])
        err.append(float(np.linalg.norm(tk.center - gt[k])))
        ms.append(tk.ms)
        mode.append(tk.mode)
        occ_est.append(tk.occlusion)
    return {"error": np.array(err), "ms": np.array(ms), "mode": np.array(mode), "occ_est": np.array(occ_est),
            "occlusion": seq.occlusion}


def summarize(results: list[dict[str, np.ndarray]], mask_fn=None) -> dict[str, float]:
    """Figures over all frames after the init frame (optionally only where mask_fn(result) is True)."""
    err = np.concatenate([r["error"][1:] if mask_fn is None else r["error"][1:][mask_fn(r)[1:]] for r in results])
    ms = np.concatenate([r["ms"][1:] for r in results])
    modes = np.concatenate([r["mode"][1:] for r in results])
    if err.size == 0:
        return {"frames": 0}
    return {
        "frames": int(err.size),
        "pct_le_1px": float(100 * np.mean(err <= 1.0)),
        "pct_le_2px": float(100 * np.mean(err <= 2.0)),
        "median_px": float(np.median(err)),
        "p95_px": float(np.percentile(err, 95)),
        "max_px": float(err.max()),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "pct_lost": float(100 * np.mean(modes == "lost")),
    }
