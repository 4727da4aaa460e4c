"""VisualServo-v1's observation modes, joints as (sin, cos), is_success, K and pose in info, the third-person and
depth renders, per-episode reset options and a tracker (built-in or outside) filling the features."""

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hvs_sim  # noqa: F401  (registers the environments)
from hvs_sim.envs.visual_servo import VisualServoEnv
from hvs_sim.errors import ConfigError, InputError

SMALL = {"width": 96, "height": 72}


@pytest.mark.parametrize("mode", ["image", "image+goal", "image+goal+depth", "features"])
def test_every_observation_mode_passes_check_env(mode):
    env = VisualServoEnv(obs_mode=mode, joints="sincos", **SMALL)
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=0)
    assert set(obs) == {"image": {"image", "joints"}, "image+goal": {"image", "joints", "goal", "desired"},
                        "image+goal+depth": {"image", "joints", "goal", "desired", "depth"},
                        "features": {"features", "desired", "joints"}}[mode]
    if "depth" in obs:
        assert 0.5 < float(np.median(obs["depth"])) < 1.5  # the wall about a standoff away
    if mode == "features":
        err = np.linalg.norm(obs["features"] - obs["desired"], axis=1).mean()
        assert err == pytest.approx(info["error_px"])  # the true corners, as the reward sees them
    assert info["K"].shape == (3, 3) and info["camera_pose"].shape == (4, 4) and info["is_success"] is False


def test_joints_as_sin_cos_do_not_flip_and_v1_is_registered():
    import gymnasium as gym

    env = gym.make("hvs_sim/VisualServo-v1", **SMALL)
    obs, _ = env.reset(seed=0)
    n = 6
    s, c = obs["joints"][:n], obs["joints"][n:2 * n]
    assert np.allclose(s ** 2 + c ** 2, 1)
    q = np.arctan2(s, c)
    assert np.allclose(np.sin(q), s) and env.observation_space["joints"].shape == (3 * n,)
    env.close()


def test_renders_a_third_person_view_and_the_depth():
    env = VisualServoEnv(render_mode="rgb_array", render_size=(240, 160), **SMALL)
    env.reset(seed=0)
    view = env.render()
    assert view.shape == (160, 240, 3) and view.std() > 10
    env = VisualServoEnv(render_mode="depth_array", **SMALL)
    env.reset(seed=0)
    depth = env.render()
    assert depth.shape == (72, 96) and np.isfinite(depth).all() and depth.min() > 0


def test_reset_options_are_honoured_and_checked():
    env = VisualServoEnv(**SMALL)
    _, info = env.reset(seed=0, options={"start_offset": (0.0, 0.0, 0.0, 0.0)})
    assert info["error_px"] < 0.5  # started at the goal
    _, far = env.reset(seed=0, options={"start_offset": (0.04, 0.0, 0.0, 0.0), "camera": "phone_handheld",
                                        "scenario": "walk_by", "people": "plain"})
    assert far["error_px"] > 3 and env.scene.scenario.name == "walk_by"  # 4 cm sideways: ~4 px at 96×72
    assert env.scene.scenario.camera.sensor.name == "phone_handheld"
    for options, words in (({"gravity": 0}, "unknown reset option"), ({"camera": "nope"}, "camera"),
                           ({"start_offset": (1, 2)}, "start_offset"), ({"scenario": "nope"}, "scenario")):
        with pytest.raises(InputError, match=words):
            env.reset(seed=0, options=options)


def test_a_tracker_fills_the_features():
    with pytest.raises(ConfigError, match="obs_mode='features'"):
        VisualServoEnv(tracker="ecc", **SMALL)
    env = VisualServoEnv(obs_mode="features", tracker="klt_homography", width=320, height=240)
    obs, info = env.reset(seed=0)
    assert info["tracker_mode"] == "init"
    for _ in range(5):
        obs, _, _, _, info = env.step(np.zeros(6, np.float32))
    # the tracked box's corners (the template the tracker took inside the target) where they truly are now
    truth = env.renderer.transfer(env.tracker.flag0, env.renderer.ground_truth(occlusion=False, counts=False).corners,
                                  env.tracker.roi0)
    assert info["tracker_mode"] == "align" and np.abs(obs["features"] - truth).max() < 1.0
    assert not np.allclose(obs["desired"], env.desired)  # s* of the tracked box, not of the target's outline


def test_a_drawn_start_out_of_reach_is_drawn_again():
    env = VisualServoEnv(max_offset=0.2, **SMALL)
    for seed in range(25):  # some of these first draws put the target out of view
        _, info = env.reset(seed=seed)
        assert np.isfinite(info["error_px"])


def test_a_reset_restarts_on_the_compiled_model_and_gives_what_a_new_env_gives():
    env = VisualServoEnv(camera="phone_handheld", **SMALL)  # clear, flag wall: no part of the model is drawn
    env.reset(seed=5)
    for _ in range(3):
        env.step(np.full(6, 0.3, np.float32))
    obs, _ = env.reset(seed=7)
    fresh = VisualServoEnv(camera="phone_handheld", **SMALL)
    ref, _ = fresh.reset(seed=7)
    assert env.model_builds == 1  # the second episode restarted on the first one's model
    for _ in range(10):  # and runs exactly as in a new env
        obs, reward, *_ = env.step(np.full(6, 0.3, np.float32))
        ref, ref_reward, *_ = fresh.step(np.full(6, 0.3, np.float32))
    assert np.array_equal(obs["image"], ref["image"]) and np.array_equal(obs["joints"], ref["joints"])
    assert reward == ref_reward


def test_a_new_look_or_camera_builds_a_new_model_and_fixed_appearance_keeps_one():
    people = VisualServoEnv(scenario="walk_by", **SMALL)  # each seed draws the people's clothes: a new model
    for seed in range(3):
        people.reset(seed=seed)
    assert people.model_builds == 3
    fixed = VisualServoEnv(scenario="walk_by", appearance="fixed", **SMALL)
    first, _ = fixed.reset(seed=0)
    for _ in range(2):
        fixed.reset()
    assert fixed.model_builds == 1
    again, _ = fixed.reset(seed=0)  # a seeded reset repeats its episode from any earlier state
    assert np.array_equal(first["image"], again["image"])
    fixed.reset(seed=0, options={"camera": "webcam"})
    assert fixed.model_builds == 2
    with pytest.raises(ConfigError, match="appearance"):
        VisualServoEnv(appearance="random", **SMALL)


def test_restart_refuses_a_scenario_with_another_model():
    import dataclasses

    from hvs_sim.scene.scenarios import make_scenario
    from hvs_sim.scene.world import Scene, model_key

    scene = Scene(make_scenario("clear", mount="arm"))
    assert model_key(dataclasses.replace(scene.scenario, seed=9)) == model_key(scene.scenario)  # flags only
    with pytest.raises(ConfigError, match="build a new Scene"):
        scene.restart(dataclasses.replace(scene.scenario, standoff=1.0))
