"""Where the homography hybrid's corner bias at the servo goal comes from (issue 14).

The issue's tilted start (0.03, −0.02, 0.06 m, 10°, 8°, −8°) on `clear`, the `ideal` camera at 4× multisampling
(no sensor noise, little aliasing), the arm driven by ground-truth features for 160 steps. Then, for templates
taken at several steps of that run, ECC (hvs_sim.tracking.ecc, as the hybrid refines a homography) is started
at the TRUE homography on the last frame: where it ends is the bias of its optimum, not a tracking error.

Variants:
  mip        the scene as rendered (MuJoCo's mip-mapped textures, no anisotropic filtering)
  aniso16    16× anisotropic filtering set on MuJoCo's 2-D textures (PyOpenGL, experiment only)
  ..._inner  the template kept `--inner` px inside its ROI, away from the flag's outline (the flags are 2 mm boxes
             4 mm proud of the board: their outline is a depth step whose parallax and side faces change with the
             view); NaN where the ROI, seen turned at that step, leaves too small a template

    python experiments/bench_servo_bias.py [--json experiments/results/servo_bias.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path

import cv2
import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from hvs_sim.errors import InputError
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.frames import roi_corners, roi_from_corners
from hvs_sim.tracking.warp import apply

START = (0.03, -0.02, 0.06, math.radians(10), math.radians(8), math.radians(-8))
TEMPLATE_STEPS = (0, 10, 20, 40, 158)
ANISOTROPY_EXT = 0x84FE  # GL_TEXTURE_MAX_ANISOTROPY(_EXT)


def set_anisotropy(loop: ServoLoop, level: float) -> None:
    from OpenGL import GL

    physics = loop.scene.physics
    ctx, m = physics.contexts, physics.model
    ids = [int(ctx.mujoco.ptr.texture[i]) for i in range(m.ntex) if m.tex_type[i] == 0]  # 2-D textures

    def apply_level():
        for t in ids:
            GL.glBindTexture(GL.GL_TEXTURE_2D, t)
            GL.glTexParameterf(GL.GL_TEXTURE_2D, ANISOTROPY_EXT, level)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    with ctx.gl.make_current() as gl:
        gl.call(apply_level)


def run(anisotropy: float, steps: int) -> list:
    scen = make_scenario("clear", mount="arm", seed=0, start_offset=START,
                         camera=CameraConfig(sensor="ideal", multisample=4))
    loop = ServoLoop(scen, "ground_truth", LoopConfig(steps=steps, keep_frames=True))
    if anisotropy > 1:
        set_anisotropy(loop, anisotropy)
    return list(loop)


def ecc_bias(records: list, j: int, inner: int) -> float:
    """Mean corner distance (px) between ECC's optimum, started at the truth on the last frame, and the truth,
    for the template taken at step j (its ROI `inner` px inside the flag's inner box)."""
    last, rj = records[-1], records[j]
    x, y, w, h = roi_from_corners(rj.gt_features)
    roi = (x + inner, y + inner, w - 2 * inner, h - 2 * inner)
    tracker = make_tracker("hybrid", warp="homography")
    try:
        tracker.init(rj.frame, roi)
    except InputError:  # the inner box of a turned flag, shrunk, is too small for a template
        return float("nan")
    al = tracker.aligner
    corners = roi_corners(roi)
    to_last = cv2.getPerspectiveTransform(rj.gt_features.astype(np.float32), last.gt_features.astype(np.float32))
    truth = apply(to_last.astype(float), corners)
    A_true = cv2.getPerspectiveTransform(corners.astype(np.float32), truth.astype(np.float32)).astype(float)
    al.work_image(last.frame)
    A = al.refine_intensity(al.to_work(A_true))
    if A is None:
        return float("nan")
    return float(np.linalg.norm(apply(al.to_full(A), corners) - truth, axis=1).mean())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default="experiments/results/servo_bias.json")
    ap.add_argument("--steps", type=int, default=160)
    ap.add_argument("--inner", type=int, default=16, help="px the '_inner' templates keep inside their ROI")
    args = ap.parse_args()
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    res = {"start_offset": list(START), "steps": args.steps, "template_steps": list(TEMPLATE_STEPS), "variants": {}}
    for name, aniso in (("mip", 1.0), ("aniso16", 16.0)):
        records = run(aniso, args.steps)
        view = [float(np.linalg.norm(records[j].pose_error[3:] - records[-1].pose_error[3:])) for j in TEMPLATE_STEPS]
        res["view_change_deg"] = view
        for inner in (0, args.inner):
            key = name if inner == 0 else f"{name}_inner"
            bias = [ecc_bias(records, j, inner) for j in TEMPLATE_STEPS]
            res["variants"][key] = [b if np.isfinite(b) else None for b in bias]  # None: no template there
            print(f"{key:14s} " + "  ".join(f"step {j} ({v:.1f}°): {b:.3f} px" for j, v, b in
                                           zip(TEMPLATE_STEPS, view, bias)), flush=True)
    out.write_text(json.dumps(res, indent=2))
    print(f"written {out}")


if __name__ == "__main__":
    main()
