"""The gym env's cost as an RL user meets it: reset time, step rate of one env, and of an AsyncVectorEnv with two spawn
workers, at the env's default size (160×120, `ideal` camera, `clear`), for the image and the features observation.

    python experiments/bench_env.py --json experiments/results/env_speed.json

A reset restarts on the last episode's compiled model where the model would be the same (the default `clear` flag
wall: always); the reference beside it is a new env for each episode, which builds and compiles the scene and its
rendering context. With people each seed draws new clothes, hence a new model: `walk_by` is measured with the default
`appearance="per_episode"` (a build each reset) and with `appearance="fixed"`, with the process's memory over 40 resets.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import hvs_sim  # noqa: F401 - registers the envs
from hvs_sim.envs.visual_servo import VisualServoEnv
from hvs_sim.outputs import write_atomic

RESETS, STEPS = 6, 200
MEMORY_RESETS = 40


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
    fresh = []  # the reference: a new env each episode builds and compiles everything
    for k in range(RESETS):
        t = time.perf_counter()
        gym.make("hvs_sim/VisualServo-v1", obs_mode=obs_mode).reset(seed=k)
        fresh.append(1e3 * (time.perf_counter() - t))
    return {"reset_ms_median": float(np.median(resets)), "reset_ms": resets, "steps_per_second": sps,
            "reset_in_steps": float(np.median(resets)) * sps / 1e3, "new_env_reset_ms_median": float(np.median(fresh)),
            "reset_speedup": float(np.median(fresh) / np.median(resets))}


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


def people(appearance: str) -> dict:
    """walk_by (textured people): reset ms, model builds and resident memory over MEMORY_RESETS resets."""
    env = VisualServoEnv(scenario="walk_by", appearance=appearance)
    env.reset(seed=0)
    rss0, resets = _rss_mb(), []
    for _ in range(MEMORY_RESETS):
        t = time.perf_counter()
        env.reset()
        resets.append(1e3 * (time.perf_counter() - t))
    return {"appearance": appearance, "reset_ms_median": float(np.median(resets)), "model_builds": env.model_builds,
            "resets": MEMORY_RESETS + 1, "rss_growth_mb": _rss_mb() - rss0,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


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
        print(f"{mode:9s} reset {s['reset_ms_median']:.0f} ms (= {s['reset_in_steps']:.0f} steps; a new env "
              f"{s['new_env_reset_ms_median']:.0f} ms, {s['reset_speedup']:.1f}x), {s['steps_per_second']:.0f} steps/s "
              f"alone, {v['env_steps_per_second']:.0f} env steps/s with 2 workers")
    out["walk_by"] = [people(a) for a in ("per_episode", "fixed")]
    for r in out["walk_by"]:
        print(f"walk_by appearance={r['appearance']:11s} reset {r['reset_ms_median']:.0f} ms, {r['model_builds']} "
              f"builds in {r['resets']} resets, memory {r['rss_growth_mb']:+.1f} MB over {MEMORY_RESETS} resets")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    write_atomic(args.json, json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
