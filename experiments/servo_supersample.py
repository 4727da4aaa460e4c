"""The 6-DOF servo loop with a supersampled camera: each pixel the mean of k×k samples of the scene
(`CameraConfig.supersample`), against the plain render. The loop, the start poses and the episode length are those of
`hvs-sim budget`'s closed loop (the servo benchmark's `clear` episodes, the homography hybrid on six DOF) on one
template (`--near-goal-inset off`, the loop's default when this was measured; `auto` for the loop's default now); seeds
210–217 by default, the held-out seeds `experiments/validate_budget.py` had then, whose plain-render runs are in
`experiments/results/budget_validation/`.

    python experiments/servo_supersample.py [--supersample 2] [--cameras ideal robot_cell] [--seeds 210 ... 217]
        [--near-goal-inset off] [--json experiments/results/servo_supersample.json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from hvs_sim.bench.splits import check_tuning_seeds
from hvs_sim.cliargs import near_goal_inset
from hvs_sim.errors import InputError
from hvs_sim.outputs import write_atomic
from hvs_sim.scene.scenarios import SUPERSAMPLE_CHOICES


def episodes(camera: str, k: int, seeds: list[int], near_goal: int | str | None = None) -> dict:
    import torch

    from hvs_sim.bench.budget import closed_loop

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    runs = []
    for seed in seeds:  # one episode at a time: closed_loop's seeds are consecutive from seed0
        runs += closed_loop(camera, 0.8, 1, seed0=seed, supersample=k, near_goal_inset_px=near_goal)
    return {"camera": camera, "supersample": k, "runs": runs, "seconds": time.perf_counter() - t0,
            "median_mm": float(np.median([r["final_pose_error_mm"] for r in runs]))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--supersample", type=int, default=2, choices=SUPERSAMPLE_CHOICES)
    ap.add_argument("--cameras", nargs="+", default=["ideal", "robot_cell"])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(210, 218)))
    ap.add_argument("--near-goal-inset", type=near_goal_inset, default="off", metavar="auto|off|PX",
                    help="the loop's near-goal template (as `hvs-sim run --near-goal-inset`; default off, as measured)")
    ap.add_argument("--json", default="experiments/results/servo_supersample.json")
    ap.add_argument("--allow-test-seeds", action="store_true",
                    help="allow servo test seeds (bench/splits.py), which figures are published on; recorded")
    args = ap.parse_args()
    check_tuning_seeds("servo", args.seeds, args.allow_test_seeds)  # tuning looks at dev seeds only
    out = Path(args.json)
    if not out.parent.is_dir():
        raise InputError(f"--json: folder {out.parent} does not exist")
    with ProcessPoolExecutor(min(2, len(args.cameras)), mp_context=mp.get_context("spawn")) as pool:
        rows = list(pool.map(episodes, args.cameras, [args.supersample] * len(args.cameras),
                             [args.seeds] * len(args.cameras), [args.near_goal_inset] * len(args.cameras)))
    for r in rows:
        each = ", ".join(f"{x['final_pose_error_mm']:.2f}" for x in r["runs"])
        print(f"{r['camera']:12s} supersample {r['supersample']}: median final pose error {r['median_mm']:.2f} mm ({each})")
    write_atomic(out, json.dumps({"allow_test_seeds": args.allow_test_seeds, "seeds": args.seeds, "rows": rows}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
