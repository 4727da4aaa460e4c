"""What MuJoCo's off-screen multisampling buys the trackers, and what it costs to render.

    python experiments/bench_multisample.py --json experiments/results/multisample.json

Renders the hand-held walk_by, pause and partial sequences (seeds 100-102) with `CameraConfig.multisample`
0 and 4 through the `ideal` and `phone_handheld` cameras, tracks each with the hybrid and ECC, and prints
% frames ≤ 1 px and ≤ 2 px, the median error, and the median RGB render ms per setting. The default of
`CameraConfig.multisample` is chosen from this table (README, *Render settings*).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import time
from pathlib import Path

import numpy as np
import torch

from hvs_sim.bench.sequences import Sequence
from hvs_sim.bench.splits import check_tuning_seeds
from hvs_sim.bench.track import run_tracker, summarize
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import make_scenario
from hvs_sim.scene.world import Scene
from hvs_sim.tracking.frames import roi_from_corners


def render_timed(scenario) -> tuple[Sequence, list[float]]:
    """The sequence (as hvs_sim.bench.sequences.make_sequence renders it) and the RGB ms of each frame."""
    scene = Scene(scenario)
    r = Renderer(scene)
    frames, gts, ms = [], [], []
    for k in range(scenario.n_frames):
        t = time.perf_counter()
        frames.append(r.rgb())
        if k:  # frame 0 creates the GL context
            ms.append(1e3 * (time.perf_counter() - t))
        gts.append(r.ground_truth(occlusion=True))
        scene.advance()
    corners = np.array([g.corners for g in gts])
    seq = Sequence(scenario, np.array(frames), corners, np.array([g.occlusion for g in gts]), roi_from_corners(corners[0]),
                   K=Renderer.intrinsics_of(scenario), distortion=scenario.camera.sensor.distortion)
    return seq, ms


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenarios", nargs="+", default=["walk_by", "pause", "partial"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[100, 101, 102])
    ap.add_argument("--cameras", nargs="+", default=["ideal", "phone_handheld"])
    ap.add_argument("--samples", nargs="+", type=int, default=[0, 4])
    ap.add_argument("--methods", nargs="+", default=["hybrid", "ecc"])
    ap.add_argument("--json", default="experiments/results/multisample.json")
    ap.add_argument("--allow-test-seeds", action="store_true",
                    help="allow track test seeds (bench/splits.py), which figures are published on; recorded")
    args = ap.parse_args()
    check_tuning_seeds("track", args.seeds, args.allow_test_seeds)  # tuning looks at dev seeds only
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(2)
    out = {"machine": platform.machine(), "scenarios": args.scenarios, "seeds": args.seeds, "results": {}}
    for cam in args.cameras:
        for n in args.samples:
            res = {m: [] for m in args.methods}
            render_ms = []
            for scen in args.scenarios:
                for seed in args.seeds:
                    base = make_scenario(scen, mount="handheld", seed=seed)
                    scenario = dataclasses.replace(base, camera=dataclasses.replace(base.camera, sensor=cam, multisample=n))
                    seq, ms = render_timed(scenario)
                    render_ms += ms
                    for m in args.methods:
                        res[m].append(run_tracker(m, seq))
            row = {"render_ms_median": float(np.median(render_ms))}
            for m in args.methods:
                s = summarize(res[m])
                row[m] = {k: s[k] for k in ("frames", "pct_le_1px", "pct_le_2px", "median_px", "p95_px")}
                print(f"{cam:15s} multisample {n}: {m:7s} {s['pct_le_1px']:5.1f} % ≤1px {s['pct_le_2px']:5.1f} % ≤2px "
                      f"median {s['median_px']:.3f} px", flush=True)
            print(f"{cam:15s} multisample {n}: render {row['render_ms_median']:.1f} ms median", flush=True)
            out["results"][f"{cam}/multisample{n}"] = row
            Path(args.json).write_text(json.dumps({**out, "allow_test_seeds": args.allow_test_seeds}, indent=2))


if __name__ == "__main__":
    main()
