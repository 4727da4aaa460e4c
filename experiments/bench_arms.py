"""What each arm costs per step, measured in one process on the same frames: scene build (MJCF, meshes, compile),
the wrist camera's render, the physics of one 30 Hz step, the driver (camera twist → joint velocities).

    python experiments/bench_arms.py --json experiments/results/arm_cost.json

640×480, `robot_cell`, `clear`, the reference start offset of the 6-DOF examples; STEPS steps of a fixed small twist,
arms interleaved round by round so that the machine's load falls on all alike; medians, with the Jaco as the reference.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from hvs_sim.scene.arms import ARM_NAMES

STEPS, ROUNDS = 40, 3
TWIST = np.array([0.01, -0.005, 0.005, 0.0, 0.02, 0.01])
START = (0.03, -0.02, 0.06, np.radians(10), np.radians(8), np.radians(-8))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default="out/arm_cost.json")
    args = ap.parse_args()
    from hvs_sim.control.arm import ArmDriver
    from hvs_sim.outputs import write_atomic
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario
    from hvs_sim.scene.world import Scene

    cam = CameraConfig(width=640, height=480, sensor="robot_cell")
    rigs, times = {}, {a: {"build_s": [], "render_ms": [], "physics_ms": [], "driver_ms": []} for a in ARM_NAMES}
    for _ in range(ROUNDS):
        for arm in ARM_NAMES:
            t = time.perf_counter()
            scene = Scene(make_scenario("clear", mount="arm", arm=arm, camera=cam, start_offset=START))
            times[arm]["build_s"].append(time.perf_counter() - t)
            rigs[arm] = (scene, Renderer(scene), ArmDriver(scene))
        for arm, (scene, renderer, driver) in rigs.items():
            renderer.rgb()  # the first render makes the GL context
            for _ in range(STEPS):
                t0 = time.perf_counter()
                cmd = driver.command(TWIST)
                t1 = time.perf_counter()
                scene.advance(cmd.qdot)
                t2 = time.perf_counter()
                renderer.rgb()
                t3 = time.perf_counter()
                times[arm]["driver_ms"].append(1e3 * (t1 - t0))
                times[arm]["physics_ms"].append(1e3 * (t2 - t1))
                times[arm]["render_ms"].append(1e3 * (t3 - t2))
    out = {"size": "640x480", "camera": "robot_cell", "steps": STEPS, "rounds": ROUNDS, "arms": {}}
    ref = {k: float(np.median(v)) for k, v in times["jaco"].items()}
    for arm in ARM_NAMES:
        med = {k: float(np.median(v)) for k, v in times[arm].items()}
        out["arms"][arm] = {**{f"{k}_median": v for k, v in med.items()},
                            **{f"{k}_vs_jaco": v / ref[k] for k, v in med.items()},
                            "vertices": int(rigs[arm][0].physics.model.mesh_vertnum.sum())}
        print(f"{arm:6s} build {med['build_s']:.2f} s, render {med['render_ms']:.1f} ms ({med['render_ms'] / ref['render_ms']:.2f}× "
              f"Jaco), physics {med['physics_ms']:.2f} ms ({med['physics_ms'] / ref['physics_ms']:.2f}×), driver "
              f"{med['driver_ms']:.2f} ms, {out['arms'][arm]['vertices']} mesh vertices")
    write_atomic(args.json, json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
