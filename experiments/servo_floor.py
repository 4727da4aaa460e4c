"""Where the 6-DOF servo's last millimetres come from: what the tracked corners say about the camera's pose at poses
AROUND the goal, split by source.

The loop stops where the tracked corners sit on s*, so a tracker error e at a pose is a pose error of −L⁺e there
(L: the interaction matrix of the template's four corners at the goal). At poses within ±`--lateral` mm along L's
two weakest directions (as `servo_pose_bias.py` draws them), the hybrid (homography), seeded at the truth, tracks:

- `exact`: the goal image itself resampled to the pose's true homography of the target's plane (cubic B-spline,
  rounded to 8 bits): an image that is exactly the template moved. What is left is the tracker and 8-bit rounding.
- `render`: the frame the renderer makes at that pose, through `ideal` (no noise). The difference from `exact` is
  what the renderer's pixels add: they are not exactly the goal image moved.
- for each noisy camera, `--frames` frames at each pose: the error of one frame, and of the mean of the frames'
  corners, which is what a loop that averages over that many frames keeps. The mean's error less the noise's share
  (one frame's / √frames) is the part no averaging removes.

Each is reported as the root mean square over the poses of the camera translation (mm) and rotation (°) that the
error stands for.

    python experiments/servo_floor.py [--poses 16] [--frames 16] [--cameras robot_cell]
        [--json experiments/results/servo_floor.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

os.environ.setdefault("MUJOCO_GL", "egl")

from hvs_sim.bench.budget import WEAK, template_roi, track_still, weak_directions, weak_offset
from hvs_sim.bench.splits import check_tuning_seeds
from hvs_sim.control.features import interaction_matrix
from hvs_sim.errors import InputError
from hvs_sim.geometry import offset_pose
from hvs_sim.outputs import write_atomic
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.scene.world import Scene
from hvs_sim.servo.parts import GOAL_FRAMES
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.frames import roi_corners
from hvs_sim.tracking.warp import perspective_transform


class Setup:
    """A camera's goal view: the renderer posed at will, the goal image and template, L⁺ and a tracker on it."""

    def __init__(self, camera: str, seed: int):
        self.scene = Scene(make_scenario("clear", mount="arm", seed=seed, camera=CameraConfig(sensor=camera)))
        self.r = Renderer(self.scene, people=False)
        self.q0 = self.scene.reference_configuration()
        with self.scene.posed(self.q0):
            self.goal, self.c0 = self.r.still_average(GOAL_FRAMES), self.r.ground_truth(occlusion=False).corners
        z, K = self.scene.scenario.standoff, self.r.K
        self.roi = template_roi(self.c0, z)
        self.roi0 = roi_corners(self.roi)
        xy = (self.roi0 - K[:2, 2]) / np.diag(K)[:2]
        self.L_pinv = np.linalg.pinv(interaction_matrix(xy, np.full(len(xy), z)))
        self.f = np.diag(K)[:2]
        _, self.Vt, _ = weak_directions(K, self.roi0, z)
        self.tracker = make_tracker("hybrid", warp="homography")
        self.tracker.init(self.goal, self.roi)

    def pose_error(self, corners: np.ndarray, truth: np.ndarray) -> np.ndarray:
        """The camera twist (m, rad) that a corner error stands for at the goal: −L⁺e, as (mm, degrees) norms."""
        v = self.L_pinv @ ((corners - truth) / self.f).ravel()
        return np.array([1e3 * np.linalg.norm(v[:3]), math.degrees(np.linalg.norm(v[3:]))])

    def track(self, frame: np.ndarray, truth: np.ndarray) -> np.ndarray:
        """The tracker's corners on one frame, seeded at the truth (budget.track_still)."""
        return track_still(self.tracker, frame, self.roi0, truth).corners

    def exact(self, truth: np.ndarray) -> np.ndarray:
        """The goal image moved by the target plane's homography from the goal to this pose (cubic B-spline, each
        channel), rounded to 8 bits."""
        Hinv = np.linalg.inv(perspective_transform(self.roi0, truth))
        h, w = self.goal.shape[:2]
        ys, xs = np.mgrid[0:h, 0:w]
        g = Hinv @ np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
        at = [(g[1] / g[2]).reshape(h, w), (g[0] / g[2]).reshape(h, w)]
        out = np.stack([ndimage.map_coordinates(self.goal[..., c].astype(np.float64), at, order=3, mode="mirror")
                        for c in range(3)], -1)
        return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def rms(rows: list) -> list[float]:
    a = np.asarray(rows, float)
    return [float(v) for v in np.sqrt(np.mean(a ** 2, axis=0))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=16)
    ap.add_argument("--frames", type=int, default=16, help="noisy frames per pose (their corners averaged)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lateral", type=float, default=5.0, help="mm along each of L's two weakest directions")
    ap.add_argument("--cameras", nargs="+", default=["robot_cell"], help="noisy camera presets")
    ap.add_argument("--json", default="experiments/results/servo_floor.json")
    ap.add_argument("--allow-test-seeds", action="store_true",
                    help="allow servo test seeds (bench/splits.py), which figures are published on; recorded")
    args = ap.parse_args()
    check_tuning_seeds("servo", [args.seed], args.allow_test_seeds)  # tuning looks at dev seeds only
    if args.poses < 2 or args.frames < 2:
        raise InputError(f"--poses and --frames must be at least 2, got {args.poses} and {args.frames}")
    out = Path(args.json)
    if not out.parent.is_dir():
        raise InputError(f"--json: folder {out.parent} does not exist")
    t0 = time.perf_counter()
    setups = {"ideal": Setup("ideal", args.seed), **{c: Setup(c, args.seed) for c in args.cameras if c != "ideal"}}
    rng = np.random.default_rng(args.seed)
    lat = args.lateral / 1e3
    offsets = [weak_offset(rng.uniform(-lat, lat, WEAK), setups["ideal"].Vt) for _ in range(args.poses)]
    rows = {"exact": [], "render": [], **{c: ([], []) for c in setups if c != "ideal"}}
    for i, off in enumerate(offsets):
        for name, s in setups.items():
            q = s.scene.solve_ik(*offset_pose(*s.scene.reference_pose(), off), q0=s.q0)
            with s.scene.posed(q):
                truth = s.r.transfer(s.c0, s.r.ground_truth(occlusion=False).corners, s.roi0)
                if name == "ideal":
                    rows["render"].append(s.pose_error(s.track(s.r.rgb(), truth), truth))
                    rows["exact"].append(s.pose_error(s.track(s.exact(truth), truth), truth))
                    continue
                corners = [s.track(f, truth) for f in s.r.still_frames(args.frames)]
            one, mean = rows[name]
            one.extend(s.pose_error(c, truth) for c in corners)
            mean.append(s.pose_error(np.mean(corners, axis=0), truth))
        print(f"pose {i + 1}/{args.poses}", end="\r", flush=True)
    result = {"poses": args.poses, "frames": args.frames, "seed": args.seed, "lateral_mm": args.lateral,
              "template_px": list(setups["ideal"].roi[2:]), "ideal": {}, "cameras": {}}
    for key in ("exact", "render"):
        mm, deg = rms(rows[key])
        result["ideal"][key] = {"rms_mm": mm, "rms_deg": deg}
        print(f"ideal {key:7s}: {mm:.2f} mm, {deg:.3f}°")
    for name in setups:
        if name == "ideal":
            continue
        one, mean = (rms(r) for r in rows[name])
        still = [math.sqrt(max(0.0, m ** 2 - o ** 2 / args.frames)) for m, o in zip(mean, one, strict=True)]
        result["cameras"][name] = {"one_frame_rms_mm": one[0], "one_frame_rms_deg": one[1],
                                   "mean_rms_mm": mean[0], "mean_rms_deg": mean[1],
                                   "not_averaged_mm": still[0], "not_averaged_deg": still[1]}
        print(f"{name}: one frame {one[0]:.2f} mm; mean of {args.frames} {mean[0]:.2f} mm, of which "
              f"{still[0]:.2f} mm no averaging removes ({still[1]:.3f}°)")
    result["wall_s"], result["allow_test_seeds"] = time.perf_counter() - t0, args.allow_test_seeds
    write_atomic(out, json.dumps(result, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
