"""Closed loop, gymnasium environment and rerun recording."""


import json

import gymnasium as gym
import numpy as np
import pytest

import hvs_sim  # noqa: F401  (registers the environment)
from hvs_sim.errors import HvsError
from hvs_sim.manifest import MANIFEST_NAME
from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.records import summarize_run

SMALL = CameraConfig(width=320, height=240)


@pytest.mark.parametrize("offset", [(0.03, -0.02, 0.06, 0.1), (-0.05, 0.03, -0.05, -0.2), (0.02, 0.04, 0.1, 0.0)])
def test_ground_truth_features_converge_with_exponential_decrease(offset):
    sc = make_scenario("clear", mount="arm", start_offset=offset, camera=SMALL)
    cfg = LoopConfig(steps=110, keep_frames=False)
    recs = list(ServoLoop(sc, "ground_truth", cfg))
    err = np.array([r.error_px for r in recs])
    s = summarize_run(recs, cfg)
    assert s["converged"] and err[-1] < 0.5
    # exponential decay: the error ratio over each 15-step window stays well below 1 in the first phase
    ratios = err[15:75:15] / err[0:60:15]
    assert np.all(ratios < 0.65), ratios
    assert np.all(np.diff(err[8:60]) < 0.05)  # monotone once the joints have spun up (~0.25 s)


def test_tracker_fault_stops_the_arm_and_is_recorded():
    sc = make_scenario("clear", mount="arm", camera=SMALL)
    loop = ServoLoop(sc, "deep_lk", LoopConfig(steps=4, keep_frames=False))

    def broken(frame):
        raise RuntimeError("boom")

    loop.tracker.update = broken
    recs = list(loop)
    assert recs[0].fault is None
    assert all(r.fault and "boom" in r.fault for r in recs[1:])
    assert all(np.all(r.twist == 0) for r in recs[1:])
    summary = summarize_run(recs, LoopConfig(steps=4))
    assert summary["fault_steps"] == 3 and "RuntimeError: boom" in summary["faults"]


@pytest.mark.parametrize("kwargs", [{"steps": 0}, {"steps": 10**7}, {"steps": 2.5}])
def test_bad_loop_settings(kwargs):
    with pytest.raises(HvsError, match="steps"):
        LoopConfig(**kwargs)


def test_bad_names_in_the_loop():
    with pytest.raises(HvsError, match="ground_truth"):
        ServoLoop(make_scenario("clear", mount="arm", camera=SMALL), "kcf")
    with pytest.raises(HvsError, match="arm"):
        ServoLoop(make_scenario("clear", mount="handheld", camera=SMALL), "deep_lk")


def test_short_run_writes_rrd_with_documented_entities(tmp_path):
    from rerun.chunk import RrdReader

    rrd = tmp_path / "run.rrd"
    summary, _ = run_episode(make_scenario("walk_by", mount="arm", camera=SMALL), "deep_lk",
                             LoopConfig(steps=5), rrd=str(rrd), progress=False, json_path=str(tmp_path / "run.json"))
    assert rrd.stat().st_size > 0 and (tmp_path / "run.json").exists()
    rows = (tmp_path / "run_steps.csv").read_text().splitlines()
    assert rows[0].startswith("step,time,mode,error_px") and len(rows) == 6  # header + one row per step
    for key in ("converged", "steps_to_converge", "final_error_px", "max_error_px_during_occlusion", "lost_steps", "timing"):
        assert key in summary
    assert {"physics", "render", "track", "control", "log"} <= set(summary["timing"])
    paths = set(RrdReader(str(rrd)).store().schema().entity_paths())
    expected = {"/world/camera", "/world/camera/image", "/world/camera/image/tracked", "/world/camera/image/ground_truth",
                "/world/camera/image/desired", "/world/trajectory", "/world/target", "/world/occluder", "/plots/error_px",
                "/plots/occlusion", "/plots/mode", "/plots/twist/vx", "/plots/joint_velocity/j1",
                "/world/wall", "/world/arm/mesh_0", "/run/config", "/run/summary", "/plots/log10_error_px"}
    assert expected <= paths, expected - paths


def test_recording_holds_every_step_written_by_the_background_writer(tmp_path):
    """The runner logs from a writer thread and plots as columns: after the run, every step's frame, plotted values
    and (when it moved) pose are in the .rrd (none lost in the queue or the plot buffer, none twice)."""
    from rerun.chunk import RrdReader

    steps = 23  # not a multiple of the plots' flush interval: the last partial batch must be sent at close
    rrd = tmp_path / "run.rrd"
    run_episode(make_scenario("walk_by", mount="arm", camera=SMALL), "ground_truth", LoopConfig(steps=steps),
                rrd=str(rrd), progress=False)
    at = {}  # entity path → the `step` of each logged row (the writer thread sets its own time context)
    for chunk in RrdReader(str(rrd)).store().stream():
        if not chunk.is_static:
            at.setdefault(chunk.entity_path, []).extend(chunk.to_record_batch().column("step").to_pylist())
    for path in ("/world/camera/image", "/plots/error_px", "/plots/twist/vx", "/plots/mode"):
        assert sorted(at.get(path, [])) == list(range(steps)), path
    # what can stand still is logged when it moved: the camera servoes every step of this run, the arm's base
    # never moves and s* never changes
    assert sorted(at["/world/camera"]) == list(range(steps))
    assert at["/world/camera/image/desired"] == [0]
    arm = [at[p] for p in at if p.startswith("/world/arm/mesh_")]
    assert [0] in arm and any(sorted(a) == list(range(steps)) for a in arm), arm


def test_a_logging_failure_in_the_writer_thread_is_reported_not_raised(tmp_path, monkeypatch):
    """A recording that fails part-way (here: the frame encoder) stops logging, and the run goes on and says so."""
    from hvs_sim.viz import rerun_log

    def broken(frame, quality=85):
        raise OSError("disk full")

    monkeypatch.setattr(rerun_log, "encode_jpeg", broken)
    summary, _ = run_episode(make_scenario("walk_by", mount="arm", camera=SMALL), "ground_truth", LoopConfig(steps=6),
                             rrd=str(tmp_path / "run.rrd"), progress=False, json_path=str(tmp_path / "run.json"))
    assert summary["steps_run"] == 6 and summary["logging_failed"] is True
    assert json.loads((tmp_path / "run.json").read_text())["logging_failed"] is True


def test_a_recording_that_cannot_be_finished_is_removed_and_the_run_json_says_so(tmp_path, monkeypatch):
    """rerun's last flush fails (a full disk killed its file writer): the run's JSON and steps CSV are written and
    name the problem, the incomplete .rrd is removed, and the dead stream is never flushed again without a bound."""
    import rerun as rr

    def dead_writer(self, **kw):
        assert 0 < kw["timeout_sec"] < 60
        raise RuntimeError("File-writer thread shut down prematurely")

    monkeypatch.setattr(rr.RecordingStream, "flush", dead_writer)
    monkeypatch.setattr(rr.RecordingStream, "disconnect", lambda self: pytest.fail("a dead sink was flushed again"))
    monkeypatch.setattr(rr, "unregister_shutdown", lambda: None)
    rrd = tmp_path / "run.rrd"
    run_episode(make_scenario("walk_by", mount="arm", camera=SMALL), "ground_truth", LoopConfig(steps=4),
                rrd=str(rrd), progress=False, json_path=str(tmp_path / "run.json"))
    saved = json.loads((tmp_path / "run.json").read_text())
    assert f"could not finish the rerun recording {rrd}" in saved["recording_error"] and saved["logging_failed"]
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != MANIFEST_NAME) == ["run.json", "run_steps.csv"]


def test_env_checker_passes_without_warnings():
    import warnings

    from gymnasium.utils.env_checker import check_env

    env = gym.make("hvs_sim/VisualServo-v0", render_mode="rgb_array")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert not caught, [str(w.message) for w in caught]
    assert env.spec.max_episode_steps == 300


def test_env_same_seed_same_rollout_and_reward_improves_when_servoing():
    def rollout(seed):
        env = gym.make("hvs_sim/VisualServo-v0")
        obs, _ = env.reset(seed=seed)
        frames, rewards = [obs["image"]], []
        for _ in range(5):
            obs, rew, _term, _trunc, _info = env.step(np.array([0.2, -0.1, 0.1, 0, 0, 0.1], np.float32))
            frames.append(obs["image"])
            rewards.append(rew)
        return np.stack(frames), rewards

    a, ra = rollout(7)
    b, rb = rollout(7)
    c, _ = rollout(8)
    assert np.array_equal(a, b) and ra == rb
    assert not np.array_equal(a[0], c[0])


def test_env_rejects_bad_settings():
    with pytest.raises(HvsError):
        gym.make("hvs_sim/VisualServo-v0", action_type="torque")
    with pytest.raises(HvsError):
        gym.make("hvs_sim/VisualServo-v0", scenario="nope")
