"""Outside methods (hvs_sim.plugins): a tracker, a law and a policy from the test package tests/plugins (installed by
`make test`'s set-up, registered by entry point), driven through every way of naming them; their faults recorded."""

import json
from pathlib import Path

import numpy as np
import pytest

import hvs_sim
from hvs_sim import plugins
from hvs_sim.cli import main
from hvs_sim.control.features import scale_depths
from hvs_sim.control.laws.dvs import luminance_interaction
from hvs_sim.control.laws.ibvs import IBVSConfig, IBVSController
from hvs_sim.control.laws.pbvs import PBVSController
from hvs_sim.control.protocol import ControlInput
from hvs_sim.errors import ConfigError
from hvs_sim.render.camera import intrinsics
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.records import summarize_run

PLUGIN_FILE = Path(__file__).parent / "plugins" / "hvs_test_plugins" / "track.py"
CAM = CameraConfig(width=320, height=240)


def _run(tracker, steps=12, scenario="clear", **loop):
    cfg = LoopConfig(steps=steps, keep_frames=False, **loop)
    recs = list(ServoLoop(make_scenario(scenario, mount="arm", camera=CAM), tracker, cfg))
    return recs, summarize_run(recs, cfg)


def make_module_level_tracker(**settings):  # registered below: importable as test_plugins:make_module_level_tracker
    from hvs_test_plugins.track import KLTHomography

    return KLTHomography(**settings)


def _refused_for_workers(name, factory):
    """A factory registered under `name` that worker processes could not import is refused for them, saying why."""
    hvs_sim.register_tracker(name, factory)
    try:
        with pytest.raises(ConfigError, match="worker processes cannot import"):
            plugins.portable("tracker", name)
    finally:
        plugins.unregister("tracker", name)


@pytest.fixture
def registered():
    hvs_sim.register_tracker("mine", make_module_level_tracker)
    yield "mine"
    plugins.unregister("tracker", "mine")


def test_the_test_package_is_installed_and_found_by_entry_point():
    assert {"klt_homography", "flaky_klt"} <= set(plugins.available("tracker"))
    assert {"plain_ibvs", "broken_law"} <= set(plugins.available("controller"))
    assert "template_policy" in plugins.available("policy")


@pytest.mark.parametrize("spelling", ["klt_homography", "hvs_test_plugins.track:make", f"{PLUGIN_FILE}:make"])
def test_an_outside_tracker_runs_the_closed_loop_by_every_spelling(spelling):
    recs, s = _run(spelling, template_from="start")
    assert s["fault_steps"] == 0 and s["controlled_dofs"] == ["vx", "vy", "vz", "wx", "wy", "wz"]
    assert np.nanmax([r.tracker_error_px for r in recs]) < 2.0  # it really tracks the target


def test_a_tracker_registered_in_python_runs_and_travels_to_workers_as_its_module(registered):
    recs, s = _run(registered, steps=6, template_from="start")
    assert s["fault_steps"] == 0 and recs[-1].tracker_error_px < 2.0
    assert plugins.portable("tracker", registered) == "test_plugins:make_module_level_tracker"
    _refused_for_workers("closure", lambda: None)


def test_a_misbehaving_tracker_and_law_are_recorded_faults_and_the_arm_holds():
    recs, s = _run("flaky_klt", steps=16, template_from="start")
    faults = [r for r in recs if r.mode == "fault"]
    assert s["fault_steps"] == len(faults) >= 3
    assert any("non-finite" in f for f in s["faults"]) and any("gave up" in f for f in s["faults"])
    assert all(np.all(r.twist == 0) for r in faults)
    recs, s = _run("ground_truth", steps=4, controller="broken_law")
    assert s["fault_steps"] == 4 and any("5 values" in f for f in s["faults"])
    assert any("non-finite twist" in f for f in s["faults"]) and s["controlled_dofs"] == ["vx", "vy", "vz", "wz"]


def test_an_outside_law_and_a_policy_servo():
    recs, s = _run("ground_truth", steps=90, controller="plain_ibvs")
    assert s["fault_steps"] == 0 and recs[-1].error_px < 0.3 * recs[0].error_px
    recs, s = _run("none", steps=60, policy="template_policy")
    assert s["fault_steps"] == 0 and s["controlled_dofs"] == ["vx", "vy", "vz"]
    assert recs[-1].error_px < recs[0].error_px and all(r.twist[3:].tolist() == [0, 0, 0] for r in recs)
    assert np.isnan(s["median_tracker_error_px"] or np.nan)  # no tracker: no tracker error is claimed


@pytest.mark.parametrize("kwargs, match", [
    ({"tracker": "nosuchpkg.mod:make"}, "cannot import module 'nosuchpkg.mod'"),
    ({"tracker": "hvs_test_plugins.track:nothing"}, "has no attribute 'nothing'.*KLTHomography"),
    ({"tracker": "no_such_name"}, "unknown tracker 'no_such_name'; accepted: .*klt_homography.*module:callable"),
    ({"tracker": "hvs_test_plugins.track:KLTHomography", "settings": {"bad": 1}}, "factory failed with TypeError"),
    ({"tracker": "hvs_test_plugins.law:make"}, "lacks init, update"),
    ({"tracker": "ground_truth", "controller": "nope.law:make"}, "cannot import module 'nope.law'"),
    ({"tracker": "hybrid", "controller": "dvs"}, "reads the images"),
    ({"tracker": "none"}, "needs a law that reads only the images"),
    ({"tracker": "hybrid", "policy": "template_policy"}, "replaces tracker and law"),
])
def test_bad_plugins_are_clear_errors_before_any_rendering(kwargs, match):
    kwargs = dict(kwargs)
    tracker, settings = kwargs.pop("tracker"), kwargs.pop("settings", {})
    with pytest.raises(ConfigError, match=match):
        ServoLoop(make_scenario("clear", mount="arm", camera=CAM), tracker, LoopConfig(steps=2, **kwargs), **settings)


def test_names_of_built_ins_and_bad_names_are_refused_at_registration():
    with pytest.raises(ConfigError, match="built-in"):
        hvs_sim.register_tracker("hybrid", make_module_level_tracker)
    with pytest.raises(ConfigError, match="built-in"):
        hvs_sim.register_controller("ibvs", make_module_level_tracker)
    with pytest.raises(ConfigError, match="invalid"):
        hvs_sim.register_policy("a:b", make_module_level_tracker)
    with pytest.raises(ConfigError, match="callable"):
        hvs_sim.register_policy("p", 3)


def test_ibvs_and_pbvs_give_the_same_twist_through_the_law_interface_as_before():
    K = intrinsics(640, 480, 45)
    desired = np.array([[260.0, 200], [380, 200], [380, 280], [260, 280]])
    f = desired + np.array([[10.0, -5], [12, -3], [9, -6], [11, -4]])
    for law in (IBVSController(K, desired, 0.8, IBVSConfig(damping=0.002), ("vx", "vy", "vz", "wx", "wy", "wz")),
                PBVSController(K, desired, 0.8, IBVSConfig())):
        s, s_star = law.points.error(f)[0], law.points.s_star
        for mode in ("align", "predict"):
            inp = ControlInput(features=s, desired=s_star, depths=scale_depths(s, s_star, 0.8), desired_depth=0.8, K=K,
                               features_px=f, desired_px=desired, mode=mode)
            assert law.compute(inp).twist.tolist() == law.compute(f, None, mode).twist.tolist()


def test_dvs_interaction_matrix_matches_finite_differences_of_a_textured_plane():
    """Intensity at fixed pixels of a camera looking at the plane Z = Z0 textured by f(X, Y), moved by a small twist:
    dI/dt against L_I v (brightness constancy)."""
    Z0 = 0.8

    def f(X, Y):
        return 100 + 40 * np.sin(9 * X + 1) * np.cos(7 * Y) + 20 * np.sin(23 * X * Y)

    rng = np.random.default_rng(0)
    x, y = rng.uniform(-0.2, 0.2, 50), rng.uniform(-0.15, 0.15, 50)
    h = 1e-6
    Ix = (f(Z0 * (x + h), Z0 * y) - f(Z0 * (x - h), Z0 * y)) / (2 * h)
    Iy = (f(Z0 * x, Z0 * (y + h)) - f(Z0 * x, Z0 * (y - h))) / (2 * h)
    L = luminance_interaction(Ix, Iy, x, y, Z0)
    dt = 1e-6
    for k in range(6):
        v = np.zeros(6)
        v[k] = 1.0
        w = v[3:] * dt
        th = np.linalg.norm(w)
        kx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / max(th, 1e-300)
        R = np.eye(3) + np.sin(th) * kx + (1 - np.cos(th)) * kx @ kx  # the new camera in the old frame
        t = v[:3] * dt
        rays = np.stack([x, y, np.ones_like(x)], 1) @ R.T
        lam = (Z0 - t[2]) / rays[:, 2]
        P = rays * lam[:, None] + t
        fd = (f(P[:, 0], P[:, 1]) - f(Z0 * x, Z0 * y)) / dt
        assert np.allclose(fd, L[:, k], rtol=1e-3, atol=1e-2 * np.abs(L[:, k]).max()), k


def test_dvs_converges_from_a_small_offset_without_a_tracker():
    cfg = LoopConfig(steps=60, keep_frames=False, controller="dvs")
    sc = make_scenario("clear", mount="arm", camera=CAM, start_offset=(0.01, 0.0, 0.0, 0.0, 0.0, 0.0))
    recs = list(ServoLoop(sc, "none", cfg))
    assert recs[-1].error_px < 0.25 * recs[0].error_px and summarize_run(recs, cfg)["fault_steps"] == 0


def test_cli_run_takes_outside_trackers_laws_and_policies(tmp_path, capsys):
    for extra in (["--tracker", f"{PLUGIN_FILE}:make", "--template-from", "start"],
                  ["--tracker", "ground_truth", "--controller", "hvs_test_plugins.law:make"],
                  ["--policy", "template_policy"], ["--controller", "dvs"]):
        js = tmp_path / "run.json"
        assert main(["run", "--scenario", "clear", "--steps", "4", "--width", "320", "--height", "240",
                     "--json", str(js), *extra]) == 0
        assert json.loads(js.read_text())["steps_run"] == 4
    out = capsys.readouterr().out
    assert "not converged at the end: image" in out  # it says why
    assert main(["run", "--tracker", "nosuch.mod:make", "--steps", "2"]) == 2
    assert "cannot import module 'nosuch.mod'" in capsys.readouterr().err


def test_bench_servo_runs_outside_methods_in_worker_processes(tmp_path, capsys):
    from hvs_sim.bench.servo import ServoBenchConfig, run_servo_bench

    methods = ("ground_truth/plain_ibvs", "{hvs_test_plugins.track:make}/{hvs_test_plugins.law:make}",
               "policy=template_policy", "flaky_klt")
    cfg = ServoBenchConfig(trackers=methods, scenarios=("clear",), episodes=1, steps=8, workers=2,
                           template_from="start", camera="ideal")
    summary = run_servo_bench(cfg, tmp_path, progress=False)
    res = summary["results"]["clear"]
    assert set(res) == set(methods) and res["flaky_klt"]["fault_steps"] >= 1
    assert res["policy=template_policy"]["controlled_dofs"] == ["vx", "vy", "vz"]
    for r in res.values():
        assert set(r["success"]) == {"hvs_sim", "cns", "felton", "visp"}
        assert 0 <= r["success"]["cns"]["ci95"][0] <= r["success"]["cns"]["ci95"][1] <= 1
    assert summary["schema"].startswith("hvs_sim.servo-results/") and summary["commit"]
    assert "| CNS |" in (tmp_path / "table.md").read_text()


def test_sweep_takes_an_outside_tracker(tmp_path):
    from hvs_sim import sweep

    spec = sweep.parse_spec('kind = "servo"\n[axes]\ntracker = ["hvs_test_plugins.track:make", "ground_truth"]\n'
                            '[fixed]\nsteps = 3\nscenario = "clear"\ncamera = "ideal"\n'
                            'template_from = "start"\n')
    counts = sweep.run_sweep(spec, tmp_path, progress=False)
    assert (counts["tasks"], counts["ran"], counts["errors"]) == (2, 2, 0)
    with pytest.raises(ConfigError, match="cannot import module"):
        sweep.parse_spec('kind = "servo"\n[axes]\ntracker = ["nosuch.mod:make"]\n')


def test_review_cases_outside_code_cannot_corrupt_or_crash(tmp_path, capsys):
    """An outside law that writes into its input changes nothing of the loop's; an image law sees no true corners; a
    policy whose reset fails, a tracker whose init answers nothing or fails in footage: clear errors or handled."""
    law = tmp_path / "law.py"
    law.write_text("import numpy as np\nclass L:\n    uses_features = False\n"
                   "    def compute(self, inp):\n        if not np.isnan(inp.features_px).all():\n"
                   "            raise AssertionError('saw the true corners')\n"
                   "        inp.K[0, 0] *= 2\n        return np.zeros(6)\n"
                   "def make():\n    return L()\n")
    recs, s = _run("none", steps=4, controller=f"{law}:make")
    assert s["fault_steps"] == 4 and all("read-only" in f for f in s["faults"])  # the write is refused, recorded
    assert abs(recs[-1].error_px - recs[0].error_px) < 1e-6  # the truth did not move
    pol = tmp_path / "pol.py"
    pol.write_text("class P:\n    def reset(self, obs):\n        raise RuntimeError('boom')\n"
                   "    def act(self, obs):\n        return [0] * 6\ndef make():\n    return P()\n")
    with pytest.raises(Exception, match="policy .* failed in reset.*boom"):
        _run("none", steps=2, policy=f"{pol}:make")
    trk = tmp_path / "trk.py"
    trk.write_text("class T:\n    warp = 'similarity'\n    def init(self, frame, roi):\n        return None\n"
                   "    def update(self, frame):\n        raise ValueError('lost it')\ndef make():\n    return T()\n")
    frames = tmp_path / "frames"
    frames.mkdir()
    import cv2

    for k in range(3):
        cv2.imwrite(str(frames / f"f{k}.png"), np.random.default_rng(k).integers(0, 255, (64, 64, 3), np.uint8))
    assert main(["track", str(frames), "--roi", "10,10,30,30", "--tracker", f"{trk}:make",
                 "--out", str(tmp_path / "o")]) == 2
    assert "failed: ValueError: lost it" in capsys.readouterr().err


def test_portable_refuses_a_partial_with_the_reason():
    import functools

    _refused_for_workers("partial_one", functools.partial(make_module_level_tracker, max_points=50))


def test_dvs_commands_only_the_dofs_it_is_given():
    from hvs_sim.control.laws.dvs import DVSController
    from hvs_sim.control.protocol import ControlInput
    from hvs_sim.render.camera import intrinsics

    rng = np.random.default_rng(0)
    import cv2

    goal = cv2.GaussianBlur(rng.integers(0, 255, (240, 320, 3), np.uint8), (0, 0), 2)
    frame = np.roll(goal, 2, axis=1)
    K = intrinsics(320, 240, 45)
    inp = ControlInput(features=np.zeros((4, 2)), desired=np.zeros((4, 2)), depths=np.ones(4), desired_depth=0.8,
                       K=K, features_px=np.zeros((4, 2)), desired_px=np.zeros((4, 2)), image=frame)
    four = DVSController(K, goal, (100, 80, 100, 80), 0.8, IBVSConfig(dofs=("vx", "vy", "vz", "wz"))).compute(inp)
    six = DVSController(K, goal, (100, 80, 100, 80), 0.8).compute(inp)
    assert four.twist[3] == four.twist[4] == 0 and four.dofs == ("vx", "vy", "vz", "wz")
    assert six.twist[4] != 0 and four.twist[0] != 0


def test_an_outside_trackers_first_answer_is_checked_against_the_corner_convention(flag_frame):
    """A tracker written to another corner convention (corners at (x, y)…(x + w, y + h), or counter-clockwise) is
    told at its first answer, with where the convention is written; one that keeps it, or merely tracks badly, not."""
    import warnings

    from hvs_sim.external import ContractWarning, ExternalTracker
    from hvs_sim.tracking.frames import roi_corners

    roi = (140, 100, 150, 100)

    class Boxed:  # the natural first version: the box's corner points
        def __init__(self, shift=(0.0, 0.0), order=(0, 1, 2, 3), on_init=True):
            self.c, self.on_init = roi_corners(roi)[list(order)] + shift, on_init

        def init(self, frame, roi):
            return {"corners": self.c} if self.on_init else None

        def update(self, frame):
            return {"corners": self.c}

    for inner, expect in ((Boxed((0.5, 0.5)), "half a pixel off"), (Boxed(order=(0, 3, 2, 1)), "counter-clockwise"),
                          (Boxed((0.5, 0.5), on_init=False), "half a pixel off"), (Boxed(), None),
                          (Boxed((3.0, -2.0)), None)):
        tracker = ExternalTracker(inner, "mine")
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            tracker.init(flag_frame, roi)
            tracker.update(flag_frame)  # the loop's step 0 on the init frame when init gave no answer
            tracker.update(flag_frame)
        notes = [str(w.message) for w in seen if issubclass(w.category, ContractWarning)]
        if expect is None:
            assert tracker.contract_note is None and not notes
        else:
            assert expect in tracker.contract_note and "docs/plugins.md" in tracker.contract_note and len(notes) == 1
    seeded = ExternalTracker(Boxed((0.5, 0.5), on_init=False), "mine")
    seeded.inner.seed = lambda A: None
    seeded.can_seed = True
    seeded.init(flag_frame, roi)
    seeded.seed(np.eye(3))  # a goal template: later answers are at seeded corners on other frames, not checked
    seeded.update(flag_frame)
    assert seeded.contract_note is None


def test_the_example_tracker_of_plugins_md_keeps_the_corner_convention(flag_frame):
    """The example a newcomer copies from docs/plugins.md runs, follows a shifted target and raises no warning."""
    import re
    from pathlib import Path

    from hvs_sim.plugins import ExternalTracker
    from hvs_sim.tracking.frames import roi_corners

    text = (Path(__file__).resolve().parents[1] / "docs/plugins.md").read_text()
    code = next(b for b in re.findall(r"```python\n(.*?)```", text, re.DOTALL) if "class TemplateTracker" in b)
    space: dict = {}
    exec(compile(code, "plugins.md", "exec"), space)  # noqa: S102 - the doc's own example
    tracker = ExternalTracker(space["make"](), "example")
    roi = (140, 100, 150, 100)
    tracker.init(flag_frame, roi)
    moved = np.roll(flag_frame, (3, 5), axis=(0, 1))  # the view shifted 5 px right, 3 px down
    track = tracker.update(moved)
    assert tracker.contract_note is None
    np.testing.assert_allclose(track.corners, roi_corners(roi) + (5, 3), atol=1e-9)


def test_a_benchmark_refuses_a_broken_outside_method_before_any_episode(tmp_path, monkeypatch):
    """Every outside factory is built once when the benchmark is configured: a tracker without update() named after
    the reference methods is refused before an episode or a sequence runs."""
    from hvs_sim.bench import servo
    from hvs_sim.bench.servo import ServoBenchConfig
    from hvs_sim.bench.track import TrackBenchConfig

    ran = []
    monkeypatch.setattr(servo, "_episode", lambda job: ran.append(job))
    with pytest.raises(ConfigError, match="lacks init, update"):
        ServoBenchConfig(trackers=("ground_truth", "hybrid:homography", "{hvs_test_plugins.law:make}"))
    with pytest.raises(ConfigError, match="lacks init, update"):
        TrackBenchConfig(methods=("hybrid", "hvs_test_plugins.law:make"))
    with pytest.raises(ConfigError, match="lacks compute"):  # a tracker named as the law
        ServoBenchConfig(trackers=("ground_truth/{hvs_test_plugins.track:make}",))
    assert not ran
    assert main(["bench", "servo", "--suite", "quick", "--methods", "{hvs_test_plugins.law:make}",
                 "--out", str(tmp_path / "q")]) == 2
    assert not ran and not any((tmp_path / "q").glob("*.json"))


def test_the_near_goal_template_is_offered_to_an_outside_tracker_that_can_take_it():
    """The loop's help near the goal is the loop's: an outside tracker with a goal template gets the automatic
    near-goal template as the built-ins do; one declaring `near_goal = False` declines it, and the run says why."""
    from hvs_test_plugins.track import KLTHomography

    from hvs_sim.servo.parts import NEAR_GOAL_AUTO

    scenario = make_scenario("clear", mount="arm", camera=CAM)
    offered = ServoLoop(scenario, "hvs_test_plugins.track:make", LoopConfig(steps=2))
    assert offered.resolved.near_goal == NEAR_GOAL_AUTO and offered.near_goal_off is None

    class Declines(KLTHomography):
        near_goal = False

    hvs_sim.register_tracker("declines_near_goal", Declines, replace=True)
    try:
        declined = ServoLoop(scenario, "declines_near_goal", LoopConfig(steps=2))
    finally:
        hvs_sim.plugins.unregister("tracker", "declines_near_goal")
    assert declined.resolved.near_goal is None and "declines the near-goal template" in declined.near_goal_off
