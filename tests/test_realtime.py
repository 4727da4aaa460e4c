"""The real-time loop's parts: a loop without evaluation renders, one arm driver, flat memory, render settings."""

import gc
import tracemalloc

import numpy as np
import pytest

from hvs_sim.control.arm import ArmDriver, camera_twist_to_world, twist_to_joint_velocities
from hvs_sim.render.renderer import Renderer
from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.scene.world import Scene
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.records import summarize_run

SMALL = CameraConfig(width=320, height=240)


def test_loop_without_evaluation_never_renders_it_and_servoes_the_same(monkeypatch):
    """evaluate=False: no segmentation render at all, and the arm moves exactly as with evaluation on
    (control reads none of it), converging from the demo's start (walk_by's default offset)."""
    sc = make_scenario("walk_by", mount="arm", camera=SMALL)
    cfg = LoopConfig(steps=100, keep_frames=False)
    with_eval = list(ServoLoop(sc, "deep_lk", cfg))
    assert any(r.occlusion > 0.1 for r in with_eval)  # the person did cross: the evaluation had something to see

    def no_render(*args, **kwargs):
        raise AssertionError("an evaluation render was made with evaluate=False")

    monkeypatch.setattr(Renderer, "_segment", no_render)
    no_eval_cfg = LoopConfig(steps=100, keep_frames=False, evaluate=False)
    without = list(ServoLoop(sc, "deep_lk", no_eval_cfg))
    assert all(np.isnan(r.occlusion) for r in without)
    for a, b in zip(with_eval, without):
        assert np.array_equal(a.twist, b.twist) and np.array_equal(a.features, b.features) and np.array_equal(a.q, b.q)
    s_eval, s_none = summarize_run(with_eval, cfg), summarize_run(without, no_eval_cfg)
    assert s_eval["converged"] and s_none["converged"]
    assert s_none["steps_to_converge"] == s_eval["steps_to_converge"]
    assert s_none["evaluated"] is False and s_none["occluded_steps"] is None
    assert s_none["max_error_px_during_occlusion"] is None and s_eval["occluded_steps"] > 0


def test_pipelined_loop_tracks_in_another_thread_acts_one_frame_later_and_converges():
    """LoopConfig(pipeline=True): frame k is tracked in a second thread while frame k + 1 renders; frame k's command
    acts from step k + 1 (the arm does not move between frames 0 and 1), the run servoes from the demo's start as
    the serial one does, the same seed gives the same run, and torch gets its threads back."""
    import threading

    import torch

    from hvs_sim.tracking.base import Tracker

    sc = make_scenario("walk_by", mount="arm", camera=SMALL)
    cfg = LoopConfig(steps=100, keep_frames=False, pipeline=True)
    threads_seen, update = set(), Tracker.update

    def where(self, frame):
        threads_seen.add(threading.current_thread().name)
        return update(self, frame)

    torch_threads = torch.get_num_threads()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Tracker, "update", where)
        piped = list(ServoLoop(sc, "deep_lk", cfg))
    assert torch.get_num_threads() == torch_threads
    assert threads_seen and all(name.startswith("hvs_sim-track") for name in threads_seen), threads_seen
    serial = list(ServoLoop(sc, "deep_lk", LoopConfig(steps=100, keep_frames=False)))
    assert np.array_equal(piped[0].q, piped[1].q) and not np.array_equal(serial[0].q, serial[1].q)
    assert np.allclose(piped[1].q, serial[0].q) and np.abs(piped[0].twist).max() > 0  # step 0's command waits a frame
    assert all(r.wall_ms is not None and r.wall_ms > 0 for r in piped + serial)  # as run, both drivers
    # it servoes as the serial loop does, a frame later (this 4-DOF run's pose sits near the 10 mm bound of
    # `converged` in both, so the image error and the pose are compared, not the flag)
    first_under = [next(i for i, r in enumerate(recs) if r.error_px < 0.5) for recs in (piped, serial)]
    assert abs(first_under[0] - first_under[1]) <= 5, first_under
    s, s_serial = summarize_run(piped, cfg), summarize_run(serial, LoopConfig(steps=100))
    assert s["final_error_px"] < 0.5 and abs(s["final_pose_error_mm"] - s_serial["final_pose_error_mm"]) < 1.0
    again = list(ServoLoop(sc, "deep_lk", cfg))
    assert all(np.array_equal(a.features, b.features) and np.array_equal(a.q, b.q) for a, b in zip(piped, again))


def test_pipelined_loop_records_a_tracker_fault_and_gives_torch_its_threads_back_when_stopped(monkeypatch):
    import torch

    from hvs_sim.tracking.base import Tracker

    update = Tracker.update

    def failing(self, frame):
        if self._calls == 2:
            raise RuntimeError("tracker broke")
        self._calls += 1
        return update(self, frame)

    monkeypatch.setattr(Tracker, "_calls", 0, raising=False)
    monkeypatch.setattr(Tracker, "update", failing)
    threads = torch.get_num_threads()
    loop = ServoLoop(make_scenario("walk_by", mount="arm", camera=SMALL), "deep_lk",
                     LoopConfig(steps=50, keep_frames=False, pipeline=True))
    run = iter(loop)
    recs = [next(run) for _ in range(5)]
    # record 0 is the init's own track; updates 1 and 2 align, update 3 raises in the worker thread
    assert [r.mode for r in recs][:4] == ["align", "align", "align", "fault"] and "tracker broke" in recs[3].fault
    assert np.all(recs[3].twist == 0) and torch.get_num_threads() == 1
    run.close()  # stopped mid-run, as on Ctrl-C: the worker ends and torch has its threads back
    assert torch.get_num_threads() == threads


def test_one_arm_driver_serves_the_loop_the_env_and_the_training_data(monkeypatch):
    calls = []
    command = ArmDriver.command

    def counting(self, twist):
        calls.append(len(calls))
        return command(self, twist)

    monkeypatch.setattr(ArmDriver, "command", counting)
    list(ServoLoop(make_scenario("clear", mount="arm", camera=SMALL), "ground_truth", LoopConfig(steps=3, keep_frames=False)))
    assert len(calls) == 3
    import gymnasium as gym

    import hvs_sim  # noqa: F401  (registers the environment)

    env = gym.make("hvs_sim/VisualServo-v0")
    env.reset(seed=0)
    env.step(np.zeros(6, np.float32))
    assert len(calls) == 4
    from hvs_sim.learn.data import arm_track

    arm_track(1000, 2)
    assert len(calls) == 6


def test_arm_driver_uses_forward_kinematics_and_reproduces_the_twist():
    scene = Scene(make_scenario("clear", mount="arm", camera=SMALL, start_offset=(0.02, -0.01, 0.03, 0.1)))
    driver = ArmDriver(scene, damping=1e-3)
    twist = np.array([0.01, -0.02, 0.015, 0.02, -0.03, 0.05])
    cmd = driver.command(twist)
    _, R = scene.camera_pose_cv()
    assert np.allclose(scene.camera_jacobian() @ cmd.qdot, camera_twist_to_world(R, twist), atol=1e-4)
    ref = twist_to_joint_velocities(scene.camera_jacobian(), camera_twist_to_world(Renderer(scene).camera_pose().R, twist),
                                    scene.joint_positions, driver.limits)
    assert np.array_equal(cmd.qdot, ref.qdot)
    before = scene.pose_error()
    scene.advance(cmd.qdot)
    moved = scene.pose_error() - before
    # the camera moved along the commanded twist: the translation in the camera frame has its sign pattern
    assert np.all(np.sign(moved[:3]) == np.sign(twist[:3]))


def test_memory_of_a_run_does_not_grow_with_its_steps(tmp_path, monkeypatch):
    """Python memory (numpy arrays included) in use while a run goes, at step 100 and at step 600: the same,
    within 100 bytes a step (the summary's per-step arrays are sized when the run starts; no records,
    frames or CSV rows are held). Keeping the records, as before, grew ~4 kB a step."""
    from hvs_sim.servo.records import RunStats

    used = {}
    add = RunStats.add

    def measured(self, r):
        add(self, r)
        if self.n in (100, 600):
            gc.collect()  # what reference cycles hold until the collector runs is not growth
            used[self.n] = tracemalloc.get_traced_memory()[0]

    monkeypatch.setattr(RunStats, "add", measured)
    tracemalloc.start()
    try:
        run_episode(make_scenario("walk_by", mount="arm", camera=CameraConfig(width=160, height=120)), "ground_truth",
                    LoopConfig(steps=600, keep_frames=False), progress=False, json_path=str(tmp_path / "run.json"))
    finally:
        tracemalloc.stop()
    assert used[600] - used[100] < 100 * 500, used
    rows = (tmp_path / "run_steps.csv").read_text().splitlines()
    assert len(rows) == 601  # every step was written as it came


def test_multisample_is_a_camera_setting_that_reaches_the_renderer():
    on = Scene(make_scenario("clear", mount="arm", camera=CameraConfig(width=160, height=120, multisample=4)))
    off = Scene(make_scenario("clear", mount="arm", camera=CameraConfig(width=160, height=120, multisample=0)))
    assert on.physics.model.vis.quality.offsamples == 4 and off.physics.model.vis.quality.offsamples == 0
    a, b = Renderer(on).rgb().astype(int), Renderer(off).rgb().astype(int)
    # anti-aliasing changes edge pixels only: the images agree on average, not pixel for pixel
    assert np.abs(a - b).mean() < 3.0 and (np.abs(a - b).max(axis=2) > 20).sum() > 50


@pytest.mark.parametrize("bad", [1, 3, 16, "4", 4.0])
def test_bad_multisample_is_refused(bad):
    from hvs_sim.errors import ConfigError

    with pytest.raises(ConfigError, match="multisample"):
        CameraConfig(multisample=bad)


@pytest.mark.parametrize("bad", [0, 4, True, "2", 2.0])
def test_bad_supersample_is_refused(bad):
    from hvs_sim.errors import ConfigError

    with pytest.raises(ConfigError, match="supersample"):
        CameraConfig(supersample=bad)


def test_a_supersampled_render_larger_than_the_largest_side_is_refused():
    from hvs_sim.errors import ConfigError

    with pytest.raises(ConfigError, match="at most 4096"):
        CameraConfig(width=2048, height=1536, supersample=3)
    assert CameraConfig(width=2048, height=1536, supersample=2).supersample == 2


def test_supersampling_with_the_motion_field_blur_is_refused():
    from hvs_sim.errors import ConfigError
    from hvs_sim.sensor import sensor_preset

    with pytest.raises(ConfigError, match="field blur"):
        CameraConfig(sensor=sensor_preset("phone_handheld", blur="field"), supersample=2)


def test_a_supersampled_pixel_is_the_mean_of_its_samples_and_moves_with_the_scene():
    """At 2× each pixel is the linear-light mean of a 2×2 block of a render at twice the size; the frame agrees with
    the plain render on average, and the target tracked across sub-pixel camera shifts errs less (the texture no
    longer aliases into patterns that move unlike the scene)."""
    import cv2

    from hvs_sim.geometry import offset_pose
    from hvs_sim.sensor import decode, encode
    from hvs_sim.servo.config import GOAL_ROI_INSET_PX
    from hvs_sim.tracking import make_tracker
    from hvs_sim.tracking.frames import inset_roi, roi_corners, roi_from_corners

    def scene(k, w=640, h=480):
        return Scene(make_scenario("clear", mount="arm", camera=CameraConfig(width=w, height=h, supersample=k)))

    ss, big = scene(2), scene(1, 1280, 960)
    assert ss.physics.model.vis.global_.offwidth >= 1280
    a = Renderer(ss).rgb()
    b = encode(cv2.resize(decode(Renderer(big).rgb()), (640, 480), interpolation=cv2.INTER_AREA))
    assert a.shape == (480, 640, 3) and np.abs(a.astype(int) - b.astype(int)).max() <= 1  # the 12-bit ADC's rounding
    plain = Renderer(scene(1)).rgb().astype(int)
    assert np.abs(plain - a.astype(int)).mean() < 3.0

    def worst_corner_error(k):
        sc = scene(k)
        r = Renderer(sc, people=False)
        q0 = sc.reference_configuration()
        with sc.posed(q0):
            goal, c0 = r.rgb(), r.ground_truth(occlusion=False).corners
        roi = inset_roi(roi_from_corners(c0), GOAL_ROI_INSET_PX)
        roi0 = roi_corners(roi)
        tracker = make_tracker("hybrid", warp="homography")
        tracker.init(goal, roi)
        errors = []
        for shift_px in (0.2, 0.3, 0.4):  # sideways camera shifts that move the target a fraction of a pixel
            q = sc.solve_ik(*offset_pose(*sc.reference_pose(), (shift_px * 0.8 / r.K[0, 0], 0, 0, 0, 0, 0)), q0=q0)
            with sc.posed(q):
                frame, gt = r.rgb(), r.ground_truth(occlusion=False).corners
            tracker.seed(np.eye(3))
            for _ in range(2):
                corners = tracker.update(frame).corners
            errors.append(np.abs(corners - r.transfer(c0, gt, roi0)).max())
        return float(np.mean(errors))

    assert worst_corner_error(2) < 0.6 * worst_corner_error(1)


def test_a_ground_truth_run_that_keeps_no_frames_renders_none_and_servoes_the_same(monkeypatch):
    """The oracle's features and the evaluation come from geometry: with nothing reading the frames (no tracker, law
    on the images, policy or recording) the camera renders none, and every step is as with the frames rendered."""
    sc = make_scenario("walk_by", mount="arm", camera=CameraConfig(width=320, height=240, sensor="phone_handheld"))
    with_frames = list(ServoLoop(sc, "ground_truth", LoopConfig(steps=40, keep_frames=True)))
    calls = []
    rgb = Renderer.rgb
    monkeypatch.setattr(Renderer, "rgb", lambda self: calls.append(1) or rgb(self))
    loop = ServoLoop(sc, "ground_truth", LoopConfig(steps=40, keep_frames=False))
    without = list(loop)
    assert not loop.renders_frames and not calls and all(r.frame is None for r in without)
    for a, b in zip(with_frames, without, strict=True):
        assert np.array_equal(a.twist, b.twist) and np.array_equal(a.q, b.q) and a.occlusion == b.occlusion
    assert ServoLoop(sc, "hybrid", LoopConfig(steps=1, keep_frames=False)).renders_frames  # a tracker reads them
