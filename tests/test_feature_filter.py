"""The two 6-DOF servo aids of the realistic camera: the goal image averaged over still frames
(`Renderer.still_average`, `LoopConfig.goal_frames`) and the feature filter predicted by the camera's own motion
(`control/feature_filter.py`, `LoopConfig.feature_filter`)."""

import math

import cv2
import numpy as np
import pytest

from hvs_sim.bench.servo import ServoBenchConfig
from hvs_sim.cli import main
from hvs_sim.control.feature_filter import FEATURE_FILTER_ALPHA, FeatureFilter
from hvs_sim.control.laws.ibvs import IBVSConfig, IBVSController
from hvs_sim.errors import ConfigError
from hvs_sim.render.camera import CameraPose, intrinsics
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.scene.world import Scene
from hvs_sim.sensor import sensor_preset
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.parts import GOAL_FRAMES
from hvs_sim.servo.records import summarize_run

K = intrinsics(640, 480, 45.0)
Z_STAR = 0.8
# a 15 cm × 10 cm target facing the camera at Z*, and its corners in the image (s*)
TARGET = np.array([[-0.075, -0.05, Z_STAR], [0.075, -0.05, Z_STAR], [0.075, 0.05, Z_STAR], [-0.075, 0.05, Z_STAR]])
TILTED = (0.03, -0.02, 0.06, math.radians(10), math.radians(8), math.radians(-8))


def _project(pose: CameraPose, world: np.ndarray) -> np.ndarray:
    uv = pose.to_camera(world) @ K.T
    return uv[:, :2] / uv[:, 2:3]


def _filter(alpha: float, **kw) -> FeatureFilter:
    return FeatureFilter(K, alpha, _project(CameraPose(np.eye(3), np.zeros(3)), TARGET), Z_STAR, **kw)


def test_the_filter_follows_the_cameras_own_motion_without_lag():
    # the camera translates (no rotation): the target stays a plane facing it, whose depth its scale gives
    # exactly, so the prediction is exact and the filtered corners are the measured ones at every step
    f = _filter(0.1)
    for k in range(30):
        pose = CameraPose(np.eye(3), np.array([0.002 * k, -0.001 * k, 0.004 * k]))
        measured = _project(pose, TARGET)
        out = f.update(measured, pose)
        assert np.abs(out - measured).max() < 1e-9, (k, np.abs(out - measured).max())
        assert not f.restarted


def test_the_filter_follows_a_tilted_target_through_the_cameras_rotation_without_lag():
    # the target tilted 15° about y and 10° about x, the camera turning and moving: the prediction from the
    # target's pose (IPPE on the last estimate) is exact for any still planar target
    tilt = cv2.Rodrigues(np.array([math.radians(10), math.radians(15), 0.0]))[0]
    centre = np.array([0.0, 0.0, Z_STAR])
    world = (TARGET - centre) @ tilt.T + centre
    f = _filter(0.1)
    for k in range(40):
        R = cv2.Rodrigues(np.array([0.004 * k, -0.006 * k, 0.01 * k]))[0]
        pose = CameraPose(R, np.array([0.003 * k, 0.002 * k, 0.003 * k]))
        measured = _project(pose, world)
        out = f.update(measured, pose)
        assert np.abs(out - measured).max() < 1e-6, (k, np.abs(out - measured).max())
    assert not f.restarted


def test_the_filter_averages_white_noise_by_the_exponential_filters_factor():
    rng = np.random.default_rng(3)
    sigma, alpha, n = 0.1, 0.1, 4000
    pose = CameraPose(np.eye(3), np.zeros(3))
    truth = _project(pose, TARGET)
    f = _filter(alpha)
    out = np.array([f.update(truth + rng.normal(0, sigma, truth.shape), pose) for _ in range(n)])[200:]
    err = out - truth
    assert np.abs(err.mean()) < 0.01  # unbiased
    expected = sigma * math.sqrt(alpha / (2 - alpha))  # 0.023 px
    assert err.std() == pytest.approx(expected, rel=0.15), (err.std(), expected)
    assert err.std() < 0.3 * sigma


def test_a_jump_restarts_the_filter_and_a_lost_frame_clears_it():
    pose = CameraPose(np.eye(3), np.zeros(3))
    truth = _project(pose, TARGET)
    f = _filter(0.1, gate_px=2.0)
    f.update(truth, pose)
    jumped = truth + [3.0, 0.0]  # re-acquired 3 px away: taken as it is, not blended
    assert np.array_equal(f.update(jumped, pose), jumped) and f.restarted
    small = jumped + [0.5, 0.0]  # within the gate: blended
    assert np.allclose(f.update(small, pose), jumped + [0.05, 0.0]) and not f.restarted
    nan = np.full((4, 2), np.nan)
    assert np.isnan(f.update(nan, pose)).all() and f.state is None
    assert np.array_equal(f.update(truth, pose, usable=True), truth)  # starts again at the measurement
    assert np.array_equal(f.update(truth + 1.0, pose, usable=False), truth + 1.0) and f.state is None


def test_filter_and_goal_frames_settings_are_checked():
    for bad in (0.0, 1.5, float("nan"), "0.1"):
        with pytest.raises(ConfigError, match="alpha"):
            _filter(bad)
    with pytest.raises(ConfigError, match="gate"):
        _filter(0.1, gate_px=0.0)
    for bad in (-0.1, 1.01, True):
        with pytest.raises(ConfigError, match="feature_filter"):
            LoopConfig(feature_filter=bad)
    for bad in (0, 257, 2.0, True):
        with pytest.raises(ConfigError, match="goal_frames"):
            LoopConfig(goal_frames=bad)
    assert main(["bench", "track", "--goal-frames", "4"]) == 2
    assert main(["bench", "track", "--feature-filter", "0.2"]) == 2
    with pytest.raises(ConfigError, match="goal_frames"):  # no episode would have a goal image
        ServoBenchConfig(template_from="start", goal_frames=16)


def test_while_the_tracker_predicts_six_dof_ibvs_commands_only_what_the_prediction_observes():
    desired = _project(CameraPose(np.eye(3), np.zeros(3)), TARGET)
    ctl = IBVSController(K, desired, Z_STAR, IBVSConfig(), dofs=("vx", "vy", "vz", "wx", "wy", "wz"))
    keystone = desired + np.array([[-0.3, 0.2], [0.3, 0.2], [-0.3, -0.2], [0.3, -0.2]])  # a tilt, seen
    aligned = ctl.compute(keystone, mode="align")
    predicted = ctl.compute(keystone, mode="predict")
    assert np.abs(aligned.twist[3:5]).max() > 1e-3  # measured corners: pitch and yaw commanded
    assert np.all(predicted.twist[3:5] == 0) and np.abs(predicted.twist).max() > 0  # predicted: not
    assert len(predicted.singular_values) == 4


def test_averaged_still_frames_cut_the_cameras_noise():
    def renderer(**sensor) -> Renderer:  # noise and auto-exposure as the preset has them; JPEG off to see the noise
        cam = CameraConfig(width=320, height=240, sensor=sensor_preset("phone_handheld", jpeg_quality=0, **sensor))
        return Renderer(Scene(make_scenario("clear", mount="arm", camera=cam)))

    ref = renderer(white_e=math.inf, read_noise_e=0.0).rgb().astype(float)
    r = renderer()
    one = r.still_average(1).astype(float)
    assert not np.array_equal(one, r.rgb())  # its noise is not the episode's first frame's
    many = r.still_average(16).astype(float)
    e1, e16 = (one - ref).std(), (many - ref).std()
    assert e1 > 2.0 and e16 < 0.35 * e1, (e1, e16)  # ~1/4 of the noise, plus rounding
    assert not np.array_equal(r.still_average(16), r.still_average(8))
    assert np.array_equal(r.still_average(16), r.still_average(16))  # seeded
    # one by one (Renderer.still_frames): each its own noise, and still_average is their rounded mean
    frames = list(r.still_frames(4))
    assert len(frames) == 4 and not np.array_equal(frames[0], frames[1])
    assert np.array_equal(np.rint(np.sum(frames, axis=0, dtype=np.float32) / np.float32(4)).astype(np.uint8),
                          r.still_average(4))
    ideal = Renderer(Scene(make_scenario("clear", mount="arm", camera=CameraConfig(width=320, height=240))))
    assert np.array_equal(ideal.still_average(16), ideal.rgb())
    assert all(np.array_equal(f, ideal.rgb()) for f in ideal.still_frames(3))
    for bad in (r.still_average, r.still_frames):  # refused when called, not when first read
        with pytest.raises(ConfigError, match="still frames"):
            bad(0)


def test_the_loop_filters_tracked_six_dof_corners_and_says_so():
    sc = make_scenario("clear", mount="arm", start_offset=TILTED)  # 640×480: the hybrid on a ~110 px target
    loop = ServoLoop(sc, "hybrid", LoopConfig(steps=4, keep_frames=False), warp="homography")
    recs = list(loop)
    s = summarize_run(recs, loop.config)
    assert (s["feature_filter"], s["goal_frames"]) == (FEATURE_FILTER_ALPHA, GOAL_FRAMES)
    # the controller's corners are the filtered ones: from the second frame on they differ from the tracker's
    assert np.array_equal(recs[0].features, recs[0].track.corners)
    assert all(not np.array_equal(r.features, r.track.corners) for r in recs[1:])
    assert all(r.mode == "align" for r in recs) and s["feature_filter_restarts"] == 0
    off = list(ServoLoop(sc, "hybrid", LoopConfig(steps=3, keep_frames=False, feature_filter=0.0), warp="homography"))
    assert all(np.array_equal(r.features, r.track.corners) for r in off)
    assert summarize_run(off, LoopConfig())["feature_filter"] == 0.0
    # exact features and the 4-DOF path are not filtered; a number of goal frames with a start template is refused
    gt = ServoLoop(sc, "ground_truth", LoopConfig(steps=1, keep_frames=False))
    assert summarize_run(list(gt), gt.config)["feature_filter"] == 0.0
    for bad in ({"feature_filter": 0.2}, {"template_from": "goal", "goal_frames": 8}):
        with pytest.raises(ConfigError, match="ground_truth"):
            ServoLoop(sc, "ground_truth", LoopConfig(steps=1, **bad))
    assert ServoLoop(sc, "ecc", LoopConfig(steps=1, keep_frames=False)).filter_alpha == 0.0
    with pytest.raises(ConfigError, match="goal_frames"):
        ServoLoop(sc, "ecc", LoopConfig(steps=1, goal_frames=4))
