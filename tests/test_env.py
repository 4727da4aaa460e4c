"""VisualServo-v0 takes bad settings and actions as clear errors, and is safe to vectorise."""

from __future__ import annotations

import math
import multiprocessing

import gymnasium as gym
import numpy as np
import pytest

import hvs_sim  # noqa: F401  (registers the environment)
from hvs_sim.envs.visual_servo import VisualServoEnv
from hvs_sim.errors import ConfigError, InputError, RenderError


@pytest.mark.parametrize("kwargs, words", [
    ({"max_offset": math.nan}, "max_offset"), ({"max_offset": -0.1}, "max_offset"), ({"hold_steps": 0}, "hold_steps"),
    ({"max_linear": math.nan}, "max_linear"), ({"width": 8}, "width"), ({"converge_px": 0}, "converge_px"),
    ({"reward": "score"}, "reward"), ({"action_type": "torque"}, "action_type"),
])
def test_bad_settings_are_config_errors(kwargs, words):
    with pytest.raises(ConfigError, match=words):
        VisualServoEnv(**kwargs)


def test_bad_actions_are_refused_and_leave_the_env_usable():
    env = VisualServoEnv(width=96, height=72)
    env.reset(seed=0)
    for bad, words in (([np.nan] * 6, "NaN"), (np.zeros(3), "shape"), (np.zeros((6, 1)), "shape"), ("go", "numbers")):
        with pytest.raises(InputError, match=words):
            env.step(bad)
    obs, reward, _, _, info = env.step(np.zeros(6, np.float32))
    assert np.isfinite(reward) and set(info) >= {"error_px", "occlusion", "converged", "held_steps"}
    assert obs["image"].shape == (72, 96, 3)


def test_normalised_reward_is_the_pixel_error_over_the_diagonal():
    env = VisualServoEnv(width=96, height=72, reward="normalised")
    env.reset(seed=1)
    _, reward, _, _, info = env.step(np.zeros(6, np.float32))
    assert reward == pytest.approx(-info["error_px"] / math.hypot(96, 72))


def _make():
    return gym.make("hvs_sim/VisualServo-v0", width=96, height=72)


@pytest.mark.slow
def test_async_vector_env_with_spawn_steps():
    envs = gym.vector.AsyncVectorEnv([_make, _make], context="spawn")
    try:
        obs, _ = envs.reset(seed=[0, 1])
        obs, rewards, *_ = envs.step(np.zeros((2, 6), np.float32))
        assert obs["image"].shape == (2, 72, 96, 3) and np.isfinite(rewards).all()
    finally:
        envs.close()


def _forked_child(queue):
    try:
        _make().reset(seed=0)
        queue.put("rendered")
    except RenderError as exc:
        queue.put(f"RenderError: {exc}")


@pytest.mark.slow
def test_a_process_forked_after_rendering_refuses_instead_of_hanging():
    env = _make()
    env.reset(seed=0)  # this process now holds GL state
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_forked_child, args=(queue,))
    child.start()
    child.join(60)
    assert not child.is_alive(), "the forked child hung"
    msg = queue.get(timeout=5)
    assert msg.startswith("RenderError") and "spawn" in msg
