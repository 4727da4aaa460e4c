"""Render-time benchmark: ms per 640×480 frame (RGB, and ground truth with occlusion) per mount.

    python experiments/bench_render.py --frames 100 --json experiments/results/render.json
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import make_scenario
from hvs_sim.scene.world import Scene


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--json", default="experiments/results/render.json")
    args = ap.parse_args()
    out = {"machine": platform.processor() or platform.machine(), "frames": args.frames}
    for mount in ("handheld", "arm"):
        for shadows in (False, True):
            scene = Scene(make_scenario("walk_by", mount=mount, shadows=shadows))
            r = Renderer(scene)
            r.rgb()  # warm-up: context creation
            rgb_ms, gt_ms = [], []
            for _ in range(args.frames if not shadows else max(10, args.frames // 5)):
                t = time.perf_counter()
                r.rgb()
                rgb_ms.append(1e3 * (time.perf_counter() - t))
                t = time.perf_counter()
                r.ground_truth()
                gt_ms.append(1e3 * (time.perf_counter() - t))
                scene.advance()
            key = f"{mount}{'_shadows' if shadows else ''}"
            out[key] = {"rgb_ms_median": float(np.median(rgb_ms)), "rgb_ms_p95": float(np.percentile(rgb_ms, 95)),
                        "ground_truth_ms_median": float(np.median(gt_ms))}
            print(f"{key:18s} rgb median {out[key]['rgb_ms_median']:.1f} ms  p95 {out[key]['rgb_ms_p95']:.1f} ms  "
                  f"ground truth (2 segmentation renders) {out[key]['ground_truth_ms_median']:.1f} ms")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
