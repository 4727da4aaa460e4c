"""Settings and inputs that were silently accepted or gave raw tracebacks now give clear HvsErrors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hvs_sim.control.laws.ibvs import IBVSConfig, IBVSController
from hvs_sim.errors import ConfigError, HvsError, InputError
from hvs_sim.scene.textures import natural_texture
from hvs_sim.tracking import make_tracker
from hvs_sim.validate import check_number

ROI = (250, 170, 120, 84)
K = np.array([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]])
DESIRED = np.array([[270.0, 200], [370, 200], [370, 280], [270, 280]])


@pytest.mark.parametrize("name, settings", [
    ("sift", {"min_inliers": 0}), ("sift", {"ransac_px": math.nan}), ("sift", {"ratio": 1.5}),
    ("ecc", {"gauss": 4}), ("ecc", {"eps": -1.0}), ("ecc", {"iterations": 2.5}),
    ("deep_lk", {"tau_pix": -1}), ("deep_lk", {"margin": -5}), ("deep_lk", {"reinit_px": math.inf}),
    ("hybrid", {"max_scale_step": 0.0}), ("hybrid", {"match_threshold": math.nan}),
])
def test_nonsense_tracker_settings_are_refused_by_name(name, settings):
    key = next(iter(settings))
    with pytest.raises(ConfigError, match=key):
        make_tracker(name, **settings)


def test_ecc_with_a_valid_odd_filter_still_tracks():
    img = natural_texture("brick", 640, 480, 3)
    tr = make_tracker("ecc", gauss=3)
    tr.init(img, ROI)
    assert tr.update(img).mode == "align"


def test_float_frames_on_the_unit_scale_are_refused_and_0_255_floats_accepted():
    img = natural_texture("brick", 640, 480, 3)
    tr = make_tracker("ecc")
    with pytest.raises(InputError, match=r"\[0, 1\].*255"):
        tr.init(img.astype(np.float32) / 255.0, ROI)
    tr.init(img.astype(np.float64), ROI)  # the 0–255 scale works as uint8 does
    assert tr.update(img.astype(np.float32)).mode == "align"


@pytest.mark.parametrize("settings", [
    {"max_linear": math.nan}, {"max_angular": -1.0}, {"gain_slope": math.nan}, {"gain_inf": math.nan},
    {"gain_inf": 5.0}, {"predict_gain": math.inf}, {"gain": math.nan},
])
def test_ibvs_config_refuses_nan_and_out_of_range(settings):
    with pytest.raises(ConfigError, match=next(iter(settings))):
        IBVSConfig(**settings)


@pytest.mark.parametrize("k, desired, words", [
    (np.full((3, 3), np.nan), DESIRED, "intrinsic"),
    (np.zeros((3, 3)), DESIRED, "fx, fy > 0"),
    (K[:2], DESIRED, "3×3"),
    (K, np.tile([[300.0, 200.0]], (4, 1)), "coincide"),
    (K, DESIRED[:2], "at least 3"),
    (K, "corners", "N×2"),
])
def test_ibvs_controller_refuses_singular_or_nan_geometry(k, desired, words):
    with pytest.raises(InputError, match=words):
        IBVSController(k, desired, 0.5)


def test_ibvs_output_is_finite_for_valid_input():
    ctl = IBVSController(K, DESIRED, 0.5, IBVSConfig(gain_inf=0.5))
    out = ctl.compute(DESIRED + 3.0)
    assert np.isfinite(out.twist).all() and out.error_px > 0


@pytest.mark.parametrize("value, ok", [(1, True), (0.5, True), (math.nan, False), (math.inf, False), (True, False),
                                       ("1", False), (None, False), (-0.1, False), (2.0, False)])
def test_check_number(value, ok):
    if ok:
        check_number("x", value, 0, 1, hi_open=False)
    else:
        with pytest.raises(HvsError, match="x must be"):
            check_number("x", value, 0, 1)


def test_joint_velocities_refuse_nan_instead_of_passing_it_on():
    from hvs_sim.control.arm import ArmLimits, twist_to_joint_velocities

    limits = ArmLimits(qdot_max=np.ones(6), q_lower=-np.ones(6) * 3, q_upper=np.ones(6) * 3)
    J = np.eye(6)
    with pytest.raises(InputError, match="finite"):
        twist_to_joint_velocities(J, np.full(6, np.nan), np.zeros(6), limits)
    with pytest.raises(InputError, match="need J"):
        twist_to_joint_velocities(J, np.zeros(3), np.zeros(6), limits)
    cmd = twist_to_joint_velocities(J, np.full(6, 0.1), np.zeros(6), limits)
    assert np.isfinite(cmd.qdot).all()


def test_public_entry_points_check_argument_types():
    """Wrong types get an HvsError that says what is accepted, never a raw TypeError (issue of careless input)."""
    import gymnasium as gym

    import hvs_sim  # noqa: F401 (registers the env)
    from hvs_sim.errors import HvsError
    from hvs_sim.tracking import make_tracker
    from hvs_sim.video import parse_roi

    with pytest.raises(HvsError, match="must be a string"):
        make_tracker(["hybrid"])
    with pytest.raises(HvsError, match="as keywords"):
        make_tracker("hybrid", 5)
    for text in ("١٢٠,80,64,48", "1_00,80,64,48"):
        with pytest.raises(HvsError, match="4 integers"):
            parse_roi(text)
    assert parse_roi(" 120, 80,64,48") == (120, 80, 64, 48)
    env = gym.make("hvs_sim/VisualServo-v0", render_mode="rgb_array").unwrapped
    with pytest.raises(HvsError, match="reset"):
        env.render()
    with pytest.raises(HvsError, match="seed must be"):
        env.reset(seed=True)
    env.reset(seed=1)
    for action in (["0.1"] * 6, np.full(6, 0.1 + 0.1j), [True] * 6):
        with pytest.raises(HvsError, match="real numbers"):
            env.step(action)
    env.close()
