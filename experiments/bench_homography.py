"""Homography tracking: accuracy on perspective warps of photos, and the hybrid's cost with it.

A. Four photos (scikit-learn's china and flower, PyWavelets' aero and ascent; never scikit-image's or
   matplotlib's, which are reserved) are warped by random perspective warps that move each corner of a
   120×84 ROI by up to ±4 px, clean and with a 1.1× exposure gain and noise (σ = 2 grey levels). Worst corner
   error per warp, for the similarity and homography feature LK, the homography with and without its
   intensity refinement (intensity_ic.py), the hybrid with the homography, and OpenCV ECC with a homography.
B. The hybrid with the similarity and with the homography warp on the same rendered hand-held
   sequences (phone_handheld camera, a tilted start pose), timed in the same run: mean corner error
   against ground truth and median ms per frame, with their ratio.

    python experiments/bench_homography.py [--out experiments/results/homography] [--frames 90]

Writes summary.json and table.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import cv2
import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

ROI = (250, 170, 120, 84)
H, W = 480, 640
AMPLITUDE_PX = 4.0
TILTED = (0.03, -0.02, 0.06, math.radians(10), math.radians(8), math.radians(-8))
PHOTOS = ("photo_china", "photo_flower", "photo_aero", "photo_ascent")
METHODS_A = {
    "deep_lk (similarity)": ("deep_lk", {}),
    "deep_lk homography, LK only": ("deep_lk", {"warp": "homography", "refine_intensity": False}),
    "deep_lk homography (+ intensity refinement)": ("deep_lk", {"warp": "homography"}),
    "hybrid homography": ("hybrid", {"warp": "homography"}),
    "ecc homography": ("ecc", {"warp": "homography"}),
}


def photo(name: str) -> np.ndarray:
    from hvs_sim.scene.textures import _photo_source

    img = _photo_source(name)
    img = np.stack([img] * 3, -1) if img.ndim == 2 else img
    return cv2.resize(np.ascontiguousarray(img), (W, H), interpolation=cv2.INTER_AREA)


def part_a(warps: int) -> dict:
    from hvs_sim.tracking import make_tracker
    from hvs_sim.tracking.frames import roi_corners

    corners = roi_corners(ROI).astype(np.float32)
    out = {}
    for condition in ("clean", "gain and noise"):
        for label, (name, settings) in METHODS_A.items():
            tr = make_tracker(name, **settings)
            errs, ms = [], []
            for p in PHOTOS:
                img = photo(p)
                tr.init(img, ROI)
                for k in range(warps):
                    rng = np.random.default_rng([k, 3])
                    shift = rng.uniform(-AMPLITUDE_PX, AMPLITUDE_PX, (4, 2)).astype(np.float32)
                    Hm = cv2.getPerspectiveTransform(corners, corners + shift)
                    frame = cv2.warpPerspective(img, Hm, (W, H), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
                    if condition != "clean":
                        frame = np.clip(1.1 * frame + rng.normal(0, 2.0, frame.shape), 0, 255).astype(np.uint8)
                    tr.seed(np.eye(3))
                    t0 = time.perf_counter()
                    tk = tr.update(frame)
                    ms.append(1e3 * (time.perf_counter() - t0))
                    true = cv2.perspectiveTransform(corners[None].astype(np.float64), Hm)[0]
                    errs.append(float(np.linalg.norm(tk.corners - true, axis=1).max()))
            e = np.array(errs)
            v = {"condition": condition, "method": label, "warps": len(e), "median_worst_corner_px": float(np.median(e)),
                 "p90_px": float(np.percentile(e, 90)), "max_px": float(e.max()), "share_le_0_1px": float(np.mean(e <= 0.1)),
                 "median_ms": float(np.median(ms))}
            out[f"{condition}: {label}"] = v
            print(f"A {condition:14s} {label:44s} median {v['median_worst_corner_px']:.3f} px  p90 {v['p90_px']:.3f}  "
                  f"max {v['max_px']:.3f} px  ≤0.1 px {100 * v['share_le_0_1px']:.0f} %  {v['median_ms']:.1f} ms")
    return out


def part_b(frames: int, scenarios: tuple[str, ...]) -> dict:
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario
    from hvs_sim.scene.world import Scene
    from hvs_sim.tracking import make_tracker
    from hvs_sim.tracking.frames import roi_corners, roi_from_corners

    out = {}
    for scen_name in scenarios:
        sc = Scene(make_scenario(scen_name, mount="handheld", seed=7, start_offset=TILTED,
                                 camera=CameraConfig(sensor="phone_handheld")))
        r = Renderer(sc)
        seq = []
        for _ in range(frames):
            seq.append((r.rgb(), r.ground_truth(occlusion=False).corners))
            sc.advance()
        roi = roi_from_corners(seq[0][1])
        roi0 = roi_corners(roi)
        per = {}
        trackers = {w: make_tracker("hybrid", warp=w) for w in ("similarity", "homography")}
        for tr in trackers.values():
            tr.init(seq[0][0], roi)
        stats = {w: ([], []) for w in trackers}
        for frame, gt_corners in seq[1:]:  # interleaved, so both see the same machine load
            gt = r.transfer(seq[0][1], gt_corners, roi0)
            for w, tr in trackers.items():
                tk = tr.update(frame)
                stats[w][0].append(float(np.linalg.norm(tk.corners - gt, axis=1).mean()))
                stats[w][1].append(tk.ms)
        for w, (e, ms) in stats.items():
            e = np.array(e)
            per[w] = {"median_corner_px": float(np.median(e)), "share_le_1px": float(np.mean(e <= 1.0)),
                      "max_px": float(e.max()), "median_ms": float(np.median(ms))}
        per["ms_ratio_homography_to_similarity"] = per["homography"]["median_ms"] / per["similarity"]["median_ms"]
        out[scen_name] = per
        print(f"B {scen_name}: similarity {per['similarity']['median_corner_px']:.3f} px {per['similarity']['median_ms']:.1f} ms"
              f" | homography {per['homography']['median_corner_px']:.3f} px {per['homography']['median_ms']:.1f} ms"
              f" | ms ratio {per['ms_ratio_homography_to_similarity']:.2f}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="experiments/results/homography")
    ap.add_argument("--warps", type=int, default=6, help="perspective warps per photo (part A)")
    ap.add_argument("--frames", type=int, default=90, help="frames per rendered sequence (part B)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    import torch

    torch.set_num_threads(2)
    summary = {"photos": part_a(args.warps), "rendered": part_b(args.frames, ("clear", "walk_by")),
               "settings": {"amplitude_px": AMPLITUDE_PX, "roi": ROI, "start_offset": TILTED, "frames": args.frames}}
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    lines = ["## A. Perspective warps of photos (worst corner error per warp, px)", "",
             "| frames | method | warps | median | p90 | max | ≤ 0.1 px | median ms |", "|---|---|---|---|---|---|---|---|"]
    for v in summary["photos"].values():
        lines.append(f"| {v['condition']} | {v['method']} | {v['warps']} | {v['median_worst_corner_px']:.3f} | {v['p90_px']:.3f} | "
                     f"{v['max_px']:.3f} | {100 * v['share_le_0_1px']:.0f} % | {v['median_ms']:.1f} |")
    lines += ["", "## B. The hybrid on rendered hand-held sequences, tilted start (mean corner error, px)", "",
              "| sequence | warp | median | ≤ 1 px | max | median ms | ms ratio |", "|---|---|---|---|---|---|---|"]
    for scen, per in summary["rendered"].items():
        for w in ("similarity", "homography"):
            v = per[w]
            ratio = f"{per['ms_ratio_homography_to_similarity']:.2f}" if w == "homography" else "1.00"
            lines.append(f"| {scen} | {w} | {v['median_corner_px']:.3f} | {100 * v['share_le_1px']:.0f} % | {v['max_px']:.2f} | "
                         f"{v['median_ms']:.1f} | {ratio} |")
    (out / "table.md").write_text("\n".join(lines) + "\n")
    print(f"results: {out}/ (summary.json, table.md)")


if __name__ == "__main__":
    main()
