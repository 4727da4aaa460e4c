"""Hash a fixed set of closed-loop episodes' records field by field, to show that a refactor changed no behaviour.

    python experiments/record_hashes.py --out /tmp/before.json        # on the tree before the change
    python experiments/record_hashes.py --check /tmp/before.json      # after: lists every field that differs

The episodes cover the loop's paths: ground-truth IBVS; the hybrid on six DOF with a goal template, the near-goal
switch and the feature filter through a walk-by (prediction, the safety rule's hold); PBVS; the pipelined loop; an
outside tracker (the test package's KLT, when installed); photometric servoing; an outside law and an outside policy
(the test package's). The gym env's episodes (`env_*`) hash each step's observation, reward, termination and info over
two seeded resets (the second restarts the compiled model). Timings and wall times are left out (they are the
machine's); everything else a StepRecord holds is hashed, floats by their bytes.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys

import numpy as np
import torch

from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop

CAM = CameraConfig(width=320, height=240)
SKIP = {"timings", "wall_ms", "frame"}
EPISODES = {  # name: (scenario, tracker, loop settings, steps)
    "ground_truth_ibvs": ("clear", "ground_truth", {}, 60),
    "hybrid_6dof_walk_by": ("walk_by", "hybrid", {"warp": "homography"}, 150),
    "hybrid_6dof_pbvs": ("clear", "hybrid", {"warp": "homography", "controller": "pbvs"}, 60),
    "hybrid_pipelined": ("pause", "hybrid", {"warp": "homography", "pipeline": True}, 120),
    "klt_start_template": ("clear", "hvs_test_plugins.track:make", {"template_from": "start"}, 40),
    "dvs_on_the_images": ("clear", "none", {"controller": "dvs"}, 40),
    "outside_law": ("clear", "hybrid", {"warp": "homography", "controller": "hvs_test_plugins.law:make"}, 40),
    "outside_policy": ("clear", "none", {"policy": "hvs_test_plugins.policy:make"}, 30),
}
TRACKER_KEYS = {"warp"}
ENV_EPISODES = {  # name: (env keywords, steps per reset); actions: the IBVS expert on the truth, or seeded draws
    "env_image_goal_depth": ({"obs_mode": "image+goal+depth", "joints": "sincos", "render_mode": "rgb_array"}, 12),
    "env_features_joint": ({"obs_mode": "features", "action_type": "joint", "scenario": "walk_by",
                            "reward": "normalised", "appearance": "fixed"}, 12),
    "env_features_klt": ({"obs_mode": "features", "tracker": "hvs_test_plugins.track:make", "camera": "phone_handheld",
                          "width": 320, "height": 240}, 12),
}
ENV_SEEDS = (5, 6)


def _digest(value) -> str:
    h = hashlib.sha256()

    def feed(v):
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            for f in dataclasses.fields(v):
                h.update(f.name.encode())
                feed(getattr(v, f.name))
        elif isinstance(v, np.ndarray):
            h.update(str(v.dtype).encode() + str(v.shape).encode())
            h.update(np.ascontiguousarray(v).tobytes())
        elif isinstance(v, (list, tuple)):
            h.update(b"[")
            for x in v:
                feed(x)
            h.update(b"]")
        elif isinstance(v, dict):
            for k in sorted(v):
                h.update(str(k).encode())
                feed(v[k])
        elif isinstance(v, float):
            h.update(np.float64(v).tobytes())
        elif hasattr(v, "__dict__") and not isinstance(v, (str, int, bool, type(None))):
            feed(vars(v))
        else:
            h.update(repr(v).encode())

    feed(value)
    return h.hexdigest()[:16]


def episode_hashes(name: str) -> dict[str, str]:
    scenario, tracker, settings, steps = EPISODES[name]
    tracker_settings = {k: v for k, v in settings.items() if k in TRACKER_KEYS}
    loop_settings = {k: v for k, v in settings.items() if k not in TRACKER_KEYS}
    cfg = LoopConfig(steps=steps, keep_frames=False, **loop_settings)
    loop = ServoLoop(make_scenario(scenario, mount="arm", seed=3, camera=CAM), tracker, cfg, **tracker_settings)
    per_field: dict[str, list] = {}
    for r in loop:
        for f in dataclasses.fields(r):
            if f.name not in SKIP:
                per_field.setdefault(f.name, []).append(getattr(r, f.name))
    if "track" in per_field:  # a Track's own wall time is the machine's too
        per_field["track"] = [None if t is None else dataclasses.replace(t, ms=0.0) for t in per_field["track"]]
    return {k: _digest(v) for k, v in sorted(per_field.items())}


def env_hashes(name: str) -> dict[str, str]:
    from hvs_sim.envs.expert import IBVSExpert
    from hvs_sim.envs.visual_servo import VisualServoEnv

    kwargs, steps = ENV_EPISODES[name]
    env = VisualServoEnv(**kwargs)
    expert = IBVSExpert(env, truth=True) if env.action_type == "twist" else None
    rng = np.random.default_rng(0)
    per_field: dict[str, list] = {}

    def add(prefix, d):
        for k, v in d.items():
            per_field.setdefault(f"{prefix}.{k}", []).append(v)

    for seed in ENV_SEEDS:
        obs, info = env.reset(seed=seed)
        add("obs", obs), add("info", info)
        for _ in range(steps):
            action = expert(obs, info) if expert is not None else rng.uniform(-1, 1, env.action_space.shape)
            obs, reward, terminated, truncated, info = env.step(action)
            add("obs", obs), add("info", info), add("step", {"reward": reward, "terminated": terminated,
                                                          "truncated": truncated})
        if env.render_mode is not None:
            add("render", {"view": env.render()})
    per_field["model_builds"] = [env.model_builds]
    env.close()
    return {k: _digest(v) for k, v in sorted(per_field.items())}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", help="write the hashes here (JSON)")
    p.add_argument("--check", help="compare with hashes written before; exit 1 on any difference")
    p.add_argument("--episodes", nargs="*", default=[*EPISODES, *ENV_EPISODES], choices=[*EPISODES, *ENV_EPISODES])
    args = p.parse_args()
    torch.set_num_threads(1)
    hashes = {}
    for name in args.episodes:
        try:
            hashes[name] = episode_hashes(name) if name in EPISODES else env_hashes(name)
        except Exception as exc:  # noqa: BLE001 - e.g. the test package is not installed
            hashes[name] = {"error": f"{type(exc).__name__}: {exc}"}
        print(name, "done", file=sys.stderr)
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(hashes, fh, indent=1)
    if args.check:
        with open(args.check) as fh:
            before = json.load(fh)
        diff = [(n, k) for n in hashes for k in set(hashes[n]) | set(before.get(n, {}))
                if hashes[n].get(k) != before.get(n, {}).get(k)]
        for n, k in sorted(diff):
            print(f"differs: {n}.{k}")
        print("identical" if not diff else f"{len(diff)} field(s) differ")
        return 1 if diff else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
