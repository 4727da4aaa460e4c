"""Where each arm's base stands and how its wrist camera is turned on the flange (hvs_sim/scene/arms.py ARMS).

    python experiments/arm_placement.py --json experiments/results/arm_placement.json

For each arm read from files, a grid of base positions (x, z) and camera mounts (turned about the tool axis): the
reference camera pose (0.8 m from the target, looking at it) solved by IK from seeded starts, scored by how far the
joints stay from their limits (capped at 0.5 rad) and how far the camera's Jacobian is from singular (its smallest
singular value, capped at 0.2). Then the servo benchmark's 20 first start poses (seeds 200–219) drawn for the best
placements: how many the arm cannot reach or cannot see the target from. The placement chosen (ARMS, recorded
here as "chosen") is, among the three best scores, the one with the largest joint margin whose start poses need
no more draws than the Jaco's.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json

import numpy as np

BASES_X, BASES_Z, ROLLS = (-0.3, -0.15, 0.0), (0.6, 0.75, 0.9), (0, 45, 90, 135, 180, -45, -90, -135)
MARGIN_CAP, SIGMA_CAP = 0.5, 0.2


def score(arm: str, base, roll) -> dict | None:
    from hvs_sim.errors import ConfigError
    from hvs_sim.scene import arms, world
    from hvs_sim.scene.scenarios import make_scenario

    arms.ARMS[arm] = dataclasses.replace(arms.ARMS[arm], base=base, camera_roll_deg=roll)
    world._HOME.pop(arm, None)
    reset, world.Scene.reset = world.Scene.reset, lambda self: None  # the model only: no start pose yet
    try:
        scene = world.Scene(make_scenario("clear", mount="arm", arm=arm, start_offset=(0, 0, 0, 0)))
    finally:
        world.Scene.reset = reset
    best = None
    for q0 in [np.zeros(len(scene.rig.joints)), *world._restart_seeds(scene, 12, 7)]:
        try:
            q = scene.solve_ik(*scene.reference_pose(), q0=q0)
        except ConfigError:
            continue
        scene.physics.bind(scene.rig.joints).qpos = q
        scene.physics.forward()
        sigma = float(np.linalg.svd(scene.camera_jacobian(), compute_uv=False)[-1])
        margin = world._limit_margin(scene, q)
        s = min(margin / MARGIN_CAP, 1.0) + min(sigma / SIGMA_CAP, 1.0)
        if best is None or s > best["score"]:
            best = {"score": s, "margin_rad": margin, "sigma_min": sigma}
    return best


def start_draws(arm: str, base, roll) -> list[int]:
    from hvs_sim.bench.servo import episode_start
    from hvs_sim.scene import arms, world
    from hvs_sim.scene.scenarios import CameraConfig

    arms.ARMS[arm] = dataclasses.replace(arms.ARMS[arm], base=base, camera_roll_deg=roll)
    world._HOME.pop(arm, None)
    return [episode_start("clear", seed, camera=CameraConfig(width=160, height=120), arm=arm)[1]
            for seed in range(200, 220)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default="out/arm_placement.json")
    args = ap.parse_args()
    from hvs_sim.outputs import write_atomic
    from hvs_sim.scene.arms import ARMS

    chosen = {name: (spec.base, spec.camera_roll_deg) for name, spec in ARMS.items()}
    out = {"jaco_start_draws": start_draws("jaco", *chosen["jaco"]), "arms": {}}
    for arm in [a for a in ARMS if a != "jaco"]:
        rows = []
        for x, z, roll in itertools.product(BASES_X, BASES_Z, ROLLS):
            best = score(arm, (x, 0.0, z), roll)
            rows.append({"base": [x, 0.0, z], "camera_roll_deg": roll, **(best or {"score": None})})
        ranked = sorted((r for r in rows if r["score"] is not None), key=lambda r: (-r["score"], -r["margin_rad"]))
        for r in ranked[:3]:
            r["start_draws"] = start_draws(arm, tuple(r["base"]), r["camera_roll_deg"])
        out["arms"][arm] = {"chosen": {"base": list(chosen[arm][0]), "camera_roll_deg": chosen[arm][1]},
                            "best": ranked[:3], "grid": rows}
        print(arm, "best:", json.dumps(ranked[:3]))
    write_atomic(args.json, json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
