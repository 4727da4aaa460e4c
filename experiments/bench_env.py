"""The gym env's cost as an RL user meets it: reset time, step rate of one env, and of an AsyncVectorEnv with two spawn
workers, at the env's default size (160×120, `ideal` camera, `clear`), for the image and the features observation.

    python experiments/bench_env.py --json experiments/results/env_speed.json

Every reset builds and compiles the scene again (no model reuse): the reset figure is that cost.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import hvs_sim  # noqa: F401 - registers the envs
from hvs_sim.outputs import write_atomic

RESETS, STEPS = 6, 200


def _make(obs_mode):
    return lambda: gym.make("hvs_sim/VisualServo-v1", obs_mode=obs_mode)


def single(obs_mode: str) -> dict:
    env = gym.make("hvs_sim/VisualServo-v1", obs_mode=obs_mode)
    resets = []
    for k in range(RESETS):
        t = time.perf_counter()
        env.reset(seed=k)
        resets.append(1e3 * (time.perf_counter() - t))
    rng = np.random.default_rng(0)
    t = time.perf_counter()
    for _ in range(STEPS):
        _, _, term, trunc, _ = env.step(rng.uniform(-0.2, 0.2, 6).astype(np.float32))
        if term or trunc:
            env.reset()
    sps = STEPS / (time.perf_counter() - t)
    env.close()
    return {"reset_ms_median": float(np.median(resets)), "reset_ms": resets, "steps_per_second": sps,
            "reset_in_steps": float(np.median(resets)) * sps / 1e3}


def vector(obs_mode: str, n: int = 2) -> dict:
    envs = gym.vector.AsyncVectorEnv([_make(obs_mode)] * n, context="spawn")
    try:
        envs.reset(seed=list(range(n)))
        rng = np.random.default_rng(0)  # the actions the single env is given
        t = time.perf_counter()
        for _ in range(STEPS // n):
            envs.step(rng.uniform(-0.2, 0.2, (n, 6)).astype(np.float32))
        return {"workers": n, "env_steps_per_second": (STEPS // n) * n / (time.perf_counter() - t)}
    finally:
        envs.close()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default="experiments/results/env_speed.json")
    args = ap.parse_args()
    out = {"size": "160x120", "camera": "ideal", "scenario": "clear", "resets": RESETS, "steps": STEPS}
    for mode in ("image", "features"):
        out[mode] = {"single": single(mode), "async_spawn": vector(mode)}
        s, v = out[mode]["single"], out[mode]["async_spawn"]
        print(f"{mode:9s} reset {s['reset_ms_median']:.0f} ms (= {s['reset_in_steps']:.0f} steps), "
              f"{s['steps_per_second']:.0f} steps/s alone, {v['env_steps_per_second']:.0f} env steps/s with 2 workers")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    write_atomic(args.json, json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
