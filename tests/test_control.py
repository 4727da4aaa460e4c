"""IBVS and arm mapping: interaction matrix and camera Jacobian against finite differences."""

import numpy as np
import pytest

from hvs_sim.control.arm import ArmLimits, camera_twist_to_world, twist_to_joint_velocities
from hvs_sim.control.features import interaction_matrix
from hvs_sim.control.laws.ibvs import IBVSConfig, IBVSController
from hvs_sim.errors import ConfigError, HvsError
from hvs_sim.geometry import rot_x, rot_y, rot_z
from hvs_sim.render.camera import intrinsics
from hvs_sim.scene.scenarios import make_scenario
from hvs_sim.scene.world import Scene


def _exp_rot(w):
    th = np.linalg.norm(w)
    if th < 1e-15:
        return np.eye(3)
    k = w / th
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * Kx + (1 - np.cos(th)) * Kx @ Kx


def test_interaction_matrix_matches_finite_differences_of_projection():
    rng = np.random.default_rng(0)
    P = np.c_[rng.uniform(-0.3, 0.3, (5, 2)), rng.uniform(0.5, 1.5, 5)]  # points in the camera frame
    xy = P[:, :2] / P[:, 2:]
    L = interaction_matrix(xy, P[:, 2])
    dt = 1e-6
    for k in range(6):
        twist = np.zeros(6)
        twist[k] = 1.0
        # the camera moves by the twist: points move by −v − ω × P in the camera frame
        R = _exp_rot(twist[3:] * dt)
        P_new = (P - twist[:3] * dt) @ R  # R^T (P − t)
        xy_new = P_new[:, :2] / P_new[:, 2:]
        fd = ((xy_new - xy) / dt).reshape(-1)
        assert np.allclose(fd, L[:, k], atol=1e-4), k


def test_controller_drives_error_down_along_the_feature_error():
    K = intrinsics(640, 480, 45)
    desired = np.array([[260.0, 200], [380, 200], [380, 280], [260, 280]])
    ctl = IBVSController(K, desired, 0.8, IBVSConfig(gain=1.0))
    shifted = desired + np.array([10.0, -5.0])
    out = ctl.compute(shifted)
    L = interaction_matrix(ctl.normalise(shifted), np.full(4, 0.8))
    # predicted feature rate opposes the error
    assert float(out.error @ (L @ out.twist)) < 0
    assert out.twist[3] == 0 and out.twist[4] == 0  # pitch and yaw are not observed: not commanded
    assert ctl.compute(shifted, mode="lost").twist.tolist() == [0.0] * 6
    half = ctl.compute(shifted, mode="predict").twist
    assert np.allclose(half, 0.5 * out.twist)


def test_adaptive_gain_goes_from_lambda0_to_lambda_inf():
    K = intrinsics(640, 480, 45)
    ctl = IBVSController(K, np.array([[250.0, 200], [350, 200], [350, 280], [250, 280]]), 0.8, IBVSConfig(gain=4.0, gain_inf=0.5, gain_slope=30))
    assert ctl.gain(0.0) == pytest.approx(4.0)
    assert ctl.gain(10.0) == pytest.approx(0.5, abs=1e-6)


@pytest.mark.parametrize("kwargs", [{"gain": 0}, {"gain": -1.0}, {"gain_inf": 3.0}, {"interaction": "both"},
                                    {"depth": "lidar"}, {"dofs": ("vx", "roll")}, {"predict_gain": 2.0}])
def test_bad_controller_settings_raise(kwargs):
    with pytest.raises(HvsError):
        IBVSConfig(**kwargs)


@pytest.fixture(scope="module")
def arm_scene():
    return Scene(make_scenario("clear", mount="arm"))


def test_camera_jacobian_matches_finite_differences(arm_scene):
    ph = arm_scene.physics
    joints = ph.bind(arm_scene.rig.joints)
    cam = ph.bind(arm_scene.rig.camera_site)
    q0 = joints.qpos.copy()
    J = arm_scene.camera_jacobian()
    eps = 1e-6
    for i in range(6):
        poses = []
        for sgn in (1, -1):
            joints.qpos = q0 + sgn * eps * np.eye(6)[i]
            ph.forward()
            poses.append((cam.xpos.copy(), cam.xmat.reshape(3, 3).copy()))
        joints.qpos = q0
        ph.forward()
        lin = (poses[0][0] - poses[1][0]) / (2 * eps)
        dR = (poses[0][1] - poses[1][1]) / (2 * eps) @ cam.xmat.reshape(3, 3).T
        ang = np.array([dR[2, 1], dR[0, 2], dR[1, 0]])
        assert np.allclose(lin, J[:3, i], atol=1e-6) and np.allclose(ang, J[3:, i], atol=1e-6)


def test_dls_twist_mapping_reproduces_the_twist_and_reports_saturation(arm_scene):
    J = arm_scene.camera_jacobian()
    lower, upper, qmax = arm_scene.joint_limits()
    limits = ArmLimits(qdot_max=qmax, q_lower=lower, q_upper=upper, damping=1e-3)
    R = rot_z(0.3) @ rot_x(0.2) @ rot_y(-0.1)
    twist = np.array([0.02, -0.01, 0.03, 0.0, 0.0, 0.05])
    cmd = twist_to_joint_velocities(J, camera_twist_to_world(R, twist), arm_scene.joint_positions, limits)
    assert not cmd.velocity_saturated
    assert np.allclose(J @ cmd.qdot, camera_twist_to_world(R, twist), atol=1e-4)
    big = twist_to_joint_velocities(J, camera_twist_to_world(R, 100 * twist), arm_scene.joint_positions, limits)
    assert big.velocity_saturated and np.all(np.abs(big.qdot) <= qmax + 1e-12)


def test_joint_limit_blocks_motion_toward_the_limit():
    limits = ArmLimits(qdot_max=np.ones(6), q_lower=np.full(6, -1.0), q_upper=np.full(6, 1.0), margin=0.1)
    J = np.eye(6)
    cmd = twist_to_joint_velocities(J, np.array([0.5, -0.5, 0, 0, 0, 0]), np.array([0.95, -0.95, 0, 0, 0, 0]), limits)
    assert cmd.limit_blocked == (0, 1) and cmd.qdot[0] == 0 and cmd.qdot[1] == 0
    away = twist_to_joint_velocities(J, np.array([-0.5, 0.5, 0, 0, 0, 0]), np.array([0.95, -0.95, 0, 0, 0, 0]), limits)
    assert away.limit_blocked == () and away.qdot[0] < 0


def test_bad_desired_depth():
    with pytest.raises(ConfigError):
        IBVSController(intrinsics(640, 480, 45), np.array([[250.0, 200], [350, 200], [350, 280], [250, 280]]), 0.0)
