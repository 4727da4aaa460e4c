"""How far the camera alone keeps the 6-DOF servo from its goal: the homography hybrid's corners with the
camera held still AT the reference pose, through the camera model and parts of it.

The servo ends where the tracked corners sit on s*, so a tracker bias at the goal itself moves the final pose, and
along L's weakest directions (sideways shift traded against tilt) a few hundredths of a pixel are millimetres. For
each scene (a servo episode's seed, `clear`) the template is the goal image as the loop takes it (the mean of
GOAL_FRAMES stills, 8 px inset), the tracker is seeded at the truth, and `--frames` frames are tracked with the arm
held at the reference configuration (time runs: auto-exposure drift and light dimming go on). Reported per variant:
the tracker's error projected on L's two weakest left singular vectors (mean = bias, sd = frame-to-frame noise, px),
and the camera translation each would stand for (mm: px / f / σ × |v_translation|), and the mean corner error.

Variants of the benchmark's `phone_handheld` camera: as it is; without JPEG; without exposure changes (no
auto-exposure drift, no light dimming); without sensor noise; `ideal` (clean renders); and the `robot_cell` camera.

    python experiments/servo_goal_noise.py [--seeds 300 301] [--frames 150]
        [--json experiments/results/servo_goal_noise.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from hvs_sim.bench.servo import episode_scenario
from hvs_sim.bench.splits import check_tuning_seeds
from hvs_sim.control.features import interaction_matrix
from hvs_sim.errors import InputError
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import CameraConfig
from hvs_sim.scene.world import Scene
from hvs_sim.sensor import sensor_preset
from hvs_sim.servo.config import GOAL_ROI_INSET_PX
from hvs_sim.servo.parts import GOAL_FRAMES
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.frames import inset_roi, roi_corners, roi_from_corners

BASE = "phone_handheld"
# what each variant turns off in the BASE camera (None: the `ideal` camera; a name: that preset as it is)
VARIANTS: dict[str, dict | str | None] = {
    BASE: {},
    "no_jpeg": {"jpeg_quality": 0},
    "no_exposure_changes": {"ae_drift": 0.0, "light_dim": 0.0},
    "no_sensor_noise": {"white_e": math.inf, "read_noise_e": 0.0},
    "ideal": None,
    "robot_cell": "robot_cell",
}
WEAK = 2  # L's weakest directions reported
BLOCK = 30  # frames per block mean (1 s at 30 Hz): a slow drift shows as blocks that differ more than the noise allows


def sensor_for(variant: str):
    off = VARIANTS[variant]
    if off is None:
        return "ideal"
    if isinstance(off, str):
        return sensor_preset(off)
    return dataclasses.replace(sensor_preset(BASE), name=variant, **off) if off else sensor_preset(BASE)


def run(seed: int, variant: str, frames: int) -> dict:
    scen = episode_scenario("clear", seed, camera=CameraConfig(sensor=sensor_for(variant)), people="textured")
    scene = Scene(scen)
    with scene.posed(scene.reference_configuration()):
        teacher = Renderer(scene, people=False)  # the goal image, as ServoLoop.goal_image takes it
        goal, c0 = teacher.still_average(GOAL_FRAMES), teacher.ground_truth(occlusion=False).corners
        camera = Renderer(scene, people=False)
        roi = inset_roi(roi_from_corners(c0), GOAL_ROI_INSET_PX)
        roi0 = roi_corners(roi)
        K = camera.K
        xy = (roi0 - K[:2, 2]) / np.diag(K)[:2]
        U, S, Vt = np.linalg.svd(interaction_matrix(xy, np.full(4, scen.standoff)))
        tracker = make_tracker("hybrid", warp="homography")
        tracker.init(goal, roi)
        tracker.seed(np.eye(3))
        weak, corner = [], []
        for _ in range(frames):
            scene.advance(None)  # the arm holds still; time, exposure and noise go on
            frame, gt = camera.rgb(), camera.ground_truth(occlusion=False).corners
            err = tracker.update(frame).corners - camera.transfer(c0, gt, roi0)
            weak.append([err.ravel() @ U[:, 5 - k] for k in range(WEAK)])
            corner.append(float(np.linalg.norm(err, axis=1).mean()))
    weak = np.array(weak)
    out = {"seed": seed, "variant": variant, "frames": frames, "mean_corner_error_px": float(np.mean(corner))}
    for k in range(WEAK):
        sigma, v = S[5 - k], Vt[5 - k]
        mm_per_px = 1e3 * np.linalg.norm(v[:3]) / (K[0, 0] * sigma)
        w = weak[:, k]
        out[f"weak{k + 1}"] = {
            "sigma": float(sigma), "mm_per_px": float(mm_per_px),
            "bias_px": float(w.mean()), "bias_mm": float(w.mean() * mm_per_px),
            "bias_se_px": float(w.std() / math.sqrt(len(w))), "sd_px": float(w.std()),
            "block_means_px": [float(w[i:i + BLOCK].mean()) for i in range(0, len(w) - BLOCK + 1, BLOCK)]}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[300, 301])
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--json", default="experiments/results/servo_goal_noise.json")
    ap.add_argument("--allow-test-seeds", action="store_true",
                    help="allow servo test seeds (bench/splits.py), which figures are published on; recorded")
    args = ap.parse_args()
    check_tuning_seeds("servo", args.seeds, args.allow_test_seeds)  # tuning looks at dev seeds only
    if args.frames < BLOCK:
        raise InputError(f"--frames must be at least {BLOCK} (one block), got {args.frames}")
    out = Path(args.json)
    if not out.parent.is_dir():
        raise InputError(f"--json: folder {out.parent} does not exist")
    rows = []
    t0 = time.perf_counter()
    try:
        for seed in args.seeds:
            for variant in args.variants:
                r = run(seed, variant, args.frames)
                rows.append(r)
                w1, w2 = r["weak1"], r["weak2"]
                print(f"seed {seed} {variant:20s} corners {r['mean_corner_error_px']:.3f} px | weakest: bias "
                      f"{w1['bias_px']:+.4f} ± {w1['bias_se_px']:.4f} px ({w1['bias_mm']:+.1f} mm), sd {w1['sd_px']:.4f}"
                      f" | 2nd: bias {w2['bias_px']:+.4f} ± {w2['bias_se_px']:.4f} px ({w2['bias_mm']:+.1f} mm), sd "
                      f"{w2['sd_px']:.4f}", flush=True)
    except KeyboardInterrupt:
        print("interrupted: writing what was measured")
    out.write_text(json.dumps({"allow_test_seeds": args.allow_test_seeds, "frames": args.frames, "goal_frames": GOAL_FRAMES, "inset_px": GOAL_ROI_INSET_PX,
                               "wall_s": time.perf_counter() - t0, "runs": rows}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
