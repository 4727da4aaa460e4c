"""The servo's safety rule (hvs_sim/control/safety.py): a loop that does not see holds still, resumes on a verified
alignment, and never leaves its workspace; for built-in and outside trackers and laws alike."""

import dataclasses

import cv2
import numpy as np
import pytest
from hvs_test_plugins.track import KLTHomography

import hvs_sim
from hvs_sim import plugins
from hvs_sim.control.safety import (
    FAULT,
    IMPLAUSIBLE,
    LOST,
    OUT_OF_IMAGE,
    PREDICTED,
    REACQUIRING,
    UNSURE,
    Envelope,
    SafetyConfig,
    SafetyGate,
)
from hvs_sim.errors import ConfigError
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.records import summarize_run

CAM = CameraConfig(width=320, height=240)
FPS = 30.0
S_STAR = np.array([[100.0, 80.0], [220.0, 80.0], [220.0, 160.0], [100.0, 160.0]])


def _gate(**settings) -> SafetyGate:
    return SafetyGate(SafetyConfig(**settings), FPS, S_STAR, 320, 240)


def test_a_prediction_carries_the_camera_no_further_than_its_travel_budget_however_fast_it_went():
    from types import SimpleNamespace

    c = SafetyConfig()
    for speed in (0.02, 0.15, 1.0):  # m/s when the target is hidden: slow, the twist bound, far beyond it
        g, x = _gate(), 0.0
        pose = lambda x: SimpleNamespace(t=np.array([x, 0.0, 0.0]), R=np.eye(3))
        g.update(S_STAR, "align", 1.0, False, None, pose(x))
        x += g.twist(np.array([speed, 0, 0, 0, 0, 0]))[0] / FPS
        for _ in range(int(2 * c.max_predict_s * FPS)):  # predicting on: the servo keeps asking for full speed
            g.update(S_STAR + 1, "predict", 0.8, False, None, pose(x))
            x += g.twist(np.array([speed, 0, 0, 0, 0, 0]))[0] / FPS
        assert 1e3 * x < c.max_predict_mm + 1e3 * speed / FPS, (speed, x)  # the step that began aligned, then ≤ D
    # turning counts as travel does
    g, turn = _gate(), 0.0
    rot = lambda a: SimpleNamespace(t=np.zeros(3), R=cv2.Rodrigues(np.array([0.0, a, 0.0]))[0])
    g.update(S_STAR, "align", 1.0, False, None, rot(0.0))
    for _ in range(int(c.max_predict_s * FPS)):
        g.update(S_STAR + 1, "predict", 0.8, False, None, rot(turn))
        turn += g.twist(np.array([0, 0, 0, 0, 1.0, 0]))[4] / FPS
    assert np.degrees(turn) < c.max_predict_deg + np.degrees(1.0 / FPS)


def test_the_gate_holds_on_lost_and_on_a_long_prediction_and_stops_along_the_last_trusted_twist():
    g = _gate()
    v = np.array([0.1, 0, 0, 0, 0, 0.2])
    assert g.update(S_STAR, "align", 1.0, False) is None
    assert np.allclose(g.twist(v), v)
    frames = int(SafetyConfig().max_predict_s * FPS)
    speed = []
    for _ in range(frames):  # a short prediction is servoed on, ever more slowly
        assert g.update(S_STAR + 1, "predict", 0.8, False) is None
        speed.append(np.linalg.norm(g.twist(v)))
    assert np.all(np.diff(speed) < 0) and speed[0] > 0.9 * np.linalg.norm(v) and speed[-1] < 1e-9
    assert g.update(S_STAR + 1, "predict", 0.8, False) == PREDICTED
    assert not np.any(g.twist(-5 * v))  # held: the law's answer on a guess is not followed
    # lost from full speed: the last trusted twist ramps to zero within decay_s, never the law's (reversed) answer
    g2 = _gate()
    g2.update(S_STAR, "align", 1.0, False)
    g2.twist(v)
    assert g2.update(S_STAR, "lost", 0.0, False) == LOST
    out = [g2.twist(-5 * v)]
    for _ in range(int(np.ceil(SafetyConfig().decay_s * FPS))):
        g2.update(S_STAR, "lost", 0.0, False)
        out.append(g2.twist(-5 * v))
    norms = [np.linalg.norm(t) for t in out]
    assert all(np.dot(t, v) >= 0 for t in out)
    assert norms[0] > 0 and np.all(np.diff(norms) < 0) and norms[-1] == 0.0


def test_the_gate_resumes_only_on_consecutive_aligned_measurements_that_agree():
    g = _gate()
    g.update(S_STAR, "align", 1.0, False)
    g.update(S_STAR, "lost", 0.0, False)
    assert g.update(S_STAR, "align", 1.0, False) == REACQUIRING
    assert g.update(S_STAR + 10, "align", 1.0, False) == REACQUIRING  # elsewhere: counting starts again
    assert g.update(S_STAR + 10.5, "align", 1.0, False) == REACQUIRING
    assert g.update(S_STAR + 10, "align", 1.0, False) is None  # three that agree
    ramp = [g.factor]
    for _ in range(10):
        g.update(S_STAR + 10, "align", 1.0, False)
        ramp.append(g.factor)
    assert ramp[0] < 1.0 and ramp[-1] == 1.0 and np.all(np.diff(ramp) >= 0)  # back up gradually


@pytest.mark.parametrize("px, confidence, jump, why", [
    (S_STAR + [300.0, 0.0], 1.0, None, OUT_OF_IMAGE),
    (np.full((4, 2), np.nan), 1.0, None, OUT_OF_IMAGE),
    (S_STAR[[0, 2, 1, 3]], 1.0, None, IMPLAUSIBLE),  # a crossed quad
    ((S_STAR - S_STAR.mean(0)) * 0.2 + S_STAR.mean(0), 1.0, None, IMPLAUSIBLE),  # 25× smaller than s*
    (S_STAR, 1.0, 80.0, IMPLAUSIBLE),  # jumped further than the camera's motion explains
    (S_STAR, 0.01, None, UNSURE),
])
def test_the_gate_judges_the_measurement_itself(px, confidence, jump, why):
    g = _gate()
    g.update(S_STAR, "align", 1.0, False)
    assert g.update(px, "align", confidence, False, jump) == why


def test_a_fault_stops_at_once_and_a_run_without_features_resumes_when_it_passes():
    g = _gate()
    g.update(None, "align", None, False)
    g.twist(np.ones(6))
    assert g.update(None, "fault", None, True) == FAULT and not np.any(g.twist(None))
    assert g.update(None, "align", None, False) is None


def test_the_gate_can_be_switched_off_for_ablations_and_refuses_bad_bounds():
    g = _gate(enabled=False)
    assert g.update(S_STAR, "lost", 0.0, False) is None and g.factor == 1.0
    for bad in ({"max_predict_s": -1}, {"min_confidence": 2}, {"max_area_ratio": 1}, {"resume_frames": 0},
                {"envelope_margin_m": 0}, {"enabled": "yes"}, {"decay_s": float("nan")}):
        with pytest.raises(ConfigError):
            SafetyConfig(**bad)
    with pytest.raises(ConfigError, match="SafetyConfig"):
        LoopConfig(safety={"enabled": False})


def test_the_envelope_stops_a_command_that_would_leave_it():
    I3 = np.eye(3)
    env = Envelope(SafetyConfig(envelope_margin_m=0.1, envelope_margin_deg=20), [0.2, 0, 0], I3, [0, 0, 0], I3)
    assert env.radius_m == pytest.approx(0.3) and env.max_deg == pytest.approx(20)
    assert env.check([0.2, 0, 0], I3, np.array([-0.15, 0, 0, 0, 0, 0]), 1 / FPS) is None
    out = env.check([0.298, 0, 0], I3, np.array([0.15, 0, 0, 0, 0, 0]), 1 / FPS)
    assert out is not None and "from the goal" in out
    out = env.check([0.0, 0, 0], I3, np.array([0, 0, 0, 0, 0, 0.6]), 1.0)  # turning 34° in a step
    assert out is not None and "turned" in out


class GoesBlind(KLTHomography):
    """A KLT tracker that, after `good` updates, answers `how`: confident garbage, a drifting prediction, or lost."""

    def __init__(self, good: int = 8, how: str = "garbage", back: int | None = None):
        super().__init__()
        self.good, self.how, self.back, self.n = good, how, back, 0
        self.rng = np.random.default_rng(0)

    def update(self, frame):
        out = super().update(frame)
        self.n += 1
        if self.n <= self.good or (self.back is not None and self.n > self.back):
            return out
        if self.how == "garbage":  # anywhere in the image, sure of itself
            return {"corners": self.rng.uniform(0, 240, (4, 2)), "mode": "align", "confidence": 1.0}
        if self.how == "drift":  # a predictor running off at 4 px a frame
            return {"corners": out["corners"] + 4.0 * (self.n - self.good), "mode": "predict"}
        return {"corners": out["corners"], "mode": "lost"}


@pytest.fixture
def blind():
    hvs_sim.register_tracker("goes_blind", GoesBlind, replace=True)
    yield "goes_blind"
    plugins.unregister("tracker", "goes_blind")


def _run(tracker, steps, safety=None, **settings):
    cfg = LoopConfig(steps=steps, keep_frames=False, template_from="start", safety=safety or SafetyConfig())
    sc = make_scenario("clear", mount="arm", camera=CAM)
    recs = list(ServoLoop(sc, tracker, cfg, **settings))
    return recs, summarize_run(recs, cfg)


@pytest.mark.parametrize("how", ["garbage", "drift"])
def test_an_outside_tracker_that_goes_blind_is_held_by_the_same_rule(blind, how):
    recs, s = _run(blind, 45, how=how)
    t = np.array([r.camera.t for r in recs])
    blind_from = 9 + (int(SafetyConfig().max_predict_s * FPS) + 1 if how == "drift" else 0)
    decay = int(np.ceil(SafetyConfig().decay_s * FPS))
    assert all(r.held_because is not None for r in recs[blind_from:])
    assert all(not np.any(r.twist) for r in recs[blind_from + decay:])
    moved_mm = 1e3 * np.linalg.norm(t[-1] - t[blind_from + decay + 2])  # the arm spun down: it stays
    assert moved_mm < 1.0, moved_mm
    assert s["held_steps"] >= len(recs) - blind_from and not s["runaway"] and s["aborted"] is None
    # without the rule the same tracker drives the arm on its garbage
    off = dataclasses.replace(SafetyConfig(), enabled=False)
    _, s_off = _run(blind, 45, safety=off, how=how)
    assert s_off["held_steps"] == 0
    assert s_off["camera_path_m"] > 1.5 * s["camera_path_m"]


def test_the_loop_resumes_servoing_once_the_target_is_verified_again(blind):
    recs, s = _run(blind, 40, how="lost", good=6, back=16)
    held = [r.held_because for r in recs]
    assert held[7] == LOST and all(h is not None for h in held[7:17])
    assert REACQUIRING in held[16:20]
    assert all(h is None for h in held[20:]) and np.any(recs[-1].twist)
    assert s["held_because"][LOST] == 10


class RunsAway:
    """An outside law that backs the camera away from the target at full speed, whatever it sees."""

    def compute(self, inp):
        return np.array([0.0, 0.0, -0.15, 0.0, 0.0, 0.0])


@pytest.fixture
def runs_away():
    hvs_sim.register_controller("runs_away", RunsAway, replace=True)
    yield "runs_away"
    plugins.unregister("controller", "runs_away")


def test_a_command_that_would_leave_the_envelope_ends_the_episode_as_aborted(runs_away):
    cfg = LoopConfig(steps=200, keep_frames=False, controller=runs_away)
    sc = make_scenario("clear", mount="arm", camera=CAM, start_offset=(0.02, 0.0, 0.03, 0.0, 0.0, 0.0))
    loop = ServoLoop(sc, "ground_truth", cfg)
    recs = list(loop)
    s = summarize_run(recs, cfg)
    assert len(recs) < 200 and recs[-1].aborted and "envelope" in recs[-1].aborted
    assert s["aborted"] == recs[-1].aborted and s["runaway"] and not s["held_to_end"]
    assert s["not_converged_because"].startswith("aborted")
    goal = loop.scene.reference_pose()[0]
    radius = np.linalg.norm(recs[0].camera.t - goal) + SafetyConfig().envelope_margin_m
    assert max(np.linalg.norm(r.camera.t - goal) for r in recs) <= radius + 1e-3  # never left


def test_the_blackout_scenario_hides_the_target_for_ten_seconds_near_the_goal():
    sc = make_scenario("blackout", mount="arm", seed=3)
    (plan,) = sc.occluders
    assert plan.kind == "pause" and plan.pause_s == 10.0
    assert plan.t_cross - plan.pause_s / 2 < 3.0 < plan.t_cross + plan.pause_s / 2 + 1.0 < sc.duration
    assert sc.duration - (plan.t_cross + plan.pause_s / 2) >= 7.0  # time to converge after the person leaves


def test_camera_drift_while_hidden_is_measured_from_where_each_hidden_stretch_began():
    from hvs_sim.servo.records import RunStats

    stats = RunStats(LoopConfig(steps=8))
    stats.camera_t[:8] = [[0, 0, 0], [0.05, 0, 0], [0.05, 0.001, 0], [0.05, 0.004, 0], [0.2, 0, 0], [0.2, 0, 0],
                          [0.2, 0.002, 0], [0.3, 0, 0]]
    hidden = np.array([False, True, True, True, False, True, True, False])
    assert stats._drift_while_hidden_mm(hidden) == pytest.approx(4.0)
