"""Fuzzing the public entry points: every input gives a clear HvsError (or a usage error) or a valid
result; never a raw traceback, never NaN out. The CLI's long work (rendering, benchmarks) is replaced
by stubs that record what they were given, so every option path is exercised in milliseconds."""

from __future__ import annotations

import contextlib
import json
import math
import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hvs_sim.cli import main
from hvs_sim.control.laws.ibvs import IBVSConfig, IBVSController
from hvs_sim.envs.visual_servo import VisualServoEnv
from hvs_sim.errors import HvsError

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
nasty_floats = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5), st.just(True),
                         st.sampled_from(["1", None]))
K = np.array([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]])
DESIRED = np.array([[270.0, 200], [370, 200], [370, 280], [270, 280]])


@FUZZ
@given(gain=nasty_floats, gain_inf=st.one_of(st.none(), nasty_floats), gain_slope=nasty_floats,
       predict_gain=nasty_floats, max_linear=nasty_floats, max_angular=nasty_floats,
       offset=st.floats(-50, 50), mode=st.sampled_from(["align", "predict"]))
def test_ibvs_config_and_output(gain, gain_inf, gain_slope, predict_gain, max_linear, max_angular, offset, mode):
    try:
        cfg = IBVSConfig(gain=gain, gain_inf=gain_inf, gain_slope=gain_slope, predict_gain=predict_gain,
                         max_linear=max_linear, max_angular=max_angular)
    except HvsError:
        return
    out = IBVSController(K, DESIRED, 0.5, cfg).compute(DESIRED + offset, mode=mode)
    assert np.isfinite(out.twist).all() and math.isfinite(out.gain)
    assert np.all(np.abs(out.twist[:3]) <= cfg.max_linear + 1e-12)


@FUZZ
@given(max_offset=nasty_floats, max_roll=nasty_floats, converge_px=nasty_floats, hold_steps=nasty_floats,
       max_linear=nasty_floats, width=st.sampled_from([96, 8, 96.5, -1, "96"]))
def test_env_constructor(max_offset, max_roll, converge_px, hold_steps, max_linear, width):
    with contextlib.suppress(HvsError):
        VisualServoEnv(width=width, height=72, max_offset=max_offset, max_roll=max_roll, converge_px=converge_px,
                       hold_steps=hold_steps, max_linear=max_linear)


@pytest.fixture(scope="module")
def env():
    e = VisualServoEnv(width=96, height=72)
    e.reset(seed=0)
    yield e
    e.close()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(action=st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=8),
    st.lists(st.floats(-3, 3), min_size=6, max_size=6),
    st.sampled_from(["fast", None, [[0.0] * 6]])))
def test_env_actions(env, action):
    try:
        obs, reward, *_ = env.step(action)
    except HvsError:
        obs, reward, *_ = env.step(np.zeros(6, np.float32))  # the env stays usable after a refused action
    assert math.isfinite(reward) and np.isfinite(obs["joints"]).all()


# ------------------------------------------------------------------------------------------ CLI


SEEN_CONFIGS = []  # the benchmark configs the stubs were given


@pytest.fixture
def stubs(monkeypatch, tmp_path):
    """Replace the long work behind each command with a stub that writes what the command reads back."""
    from hvs_sim import runner
    from hvs_sim.bench import natural, servo, track
    from hvs_sim.render import sequence

    def bench(summary):
        def run(cfg, out, progress=True, resume=False):
            SEEN_CONFIGS.append(cfg)
            Path(out, "summary.json").write_text(json.dumps({}))
            return summary
        return run

    monkeypatch.setattr(track, "run_track_bench", bench({"occlusion_scenarios": {}, "target_set": {}}))
    monkeypatch.setattr(servo, "run_servo_bench", bench({"results": {}}))
    monkeypatch.setattr(natural, "run_natural_bench",
                        bench({"overall": {}, "visible_lt_40": {}, "timing": {}, "per_kind": {}}))
    brief = dict.fromkeys(("converged", "held_to_end", "steps_to_converge", "final_error_px", "final_pose_error_mm",
                           "final_pose_error_deg", "final_controlled_pose_error_mm",
                           "final_controlled_pose_error_deg", "controlled_dofs", "max_error_px_during_occlusion",
                           "lost_steps", "predict_steps", "fault_steps", "held_steps", "steps_per_second"), 0)
    brief.update(not_converged_because="image 1.00 px > 0.5 px", faults=[], figures=[], held_because={}, aborted=None)
    monkeypatch.setattr(runner, "run_episode", lambda *a, **k: (brief, []))
    monkeypatch.setattr(sequence, "write_sequence", lambda *a, **k: {"frames": 1, "peak_occlusion": 0.0})
    gt = SimpleNamespace(corners=np.array([[1.0, 1], [9, 1], [9, 9], [1, 9]]), center=np.array([5.0, 5.0]))
    monkeypatch.setattr(sequence, "iterate_sequence", lambda *a, **k: iter([(np.zeros((16, 16, 3), np.uint8), gt)]))
    return tmp_path


INTS = st.sampled_from(["0", "1", "3", "-2", "1e3", "x", "2.5"])
NAMES = st.sampled_from(["walk_by", "pause", "nope", "hybrid", "hybird", "ecc", "arm", "handheld", "fur", ""])


def _options(draw_from: dict) -> st.SearchStrategy:
    """A random subset of the options, each with a random (often wrong) value."""
    items = [st.tuples(st.just(flag), values) for flag, values in draw_from.items()]
    return st.lists(st.one_of(*items), max_size=5)


def _run_cli(argv, capsys) -> None:
    code = main(argv)
    out = capsys.readouterr()
    assert code in (0, 2), (argv, code, out.err)
    assert "Traceback" not in out.err and "Traceback" not in out.out
    if code == 2:
        assert out.err.strip(), argv  # a refusal always says why


@FUZZ
@given(what=st.sampled_from(["track", "servo"]), opts=_options({
    "--methods": st.lists(NAMES, min_size=1, max_size=2), "--scenarios": st.lists(NAMES, min_size=1, max_size=2),
    "--mounts": st.lists(NAMES, min_size=1, max_size=2), "--seeds": st.lists(INTS, min_size=1, max_size=2),
    "--episodes": INTS, "--workers": INTS, "--camera": NAMES, "--people": NAMES, "--imagery": NAMES,
    "--sources": st.lists(NAMES, min_size=1, max_size=2), "--smoke": st.just(None), "--overwrite": st.just(None)}))
def test_cli_bench(stubs, capsys, what, opts):
    argv = ["bench", what, "--out", str(stubs / "bench")]
    for flag, value in opts:
        argv += [flag] + ([] if value is None else value if isinstance(value, list) else [value])
    _run_cli(argv, capsys)


@FUZZ
@given(command=st.sampled_from(["run", "scene"]), opts=_options({
    "--scenario": NAMES, "--seed": INTS, "--steps": INTS, "--frames": INTS, "--mount": NAMES, "--camera": NAMES,
    "--target": NAMES, "--wall": NAMES, "--people": NAMES, "--width": INTS, "--height": INTS,
    "--fovy": st.sampled_from(["45", "0", "nan", "179", "-3"]), "--tracker": NAMES, "--target-width": INTS,
    "--warp": st.sampled_from(["homography", "similarity", "affine", ""]), "--controller": NAMES,
    "--start-offset": st.sampled_from(["0,0,0,0,0,0", "0.03,-0.02,0.06,10,8,-8", "1,2", "0,0,0,0,80,0", "a,b,c,d,e,f",
                                       "0,0,0,0,0,nan"]),
    "--overwrite": st.just(None)}))
def test_cli_run_and_scene(stubs, capsys, command, opts):
    argv = [command] + (["--out", str(stubs / "scene"), "--overwrite"] if command == "scene" else
                        ["--json", str(stubs / "run.json")])
    for flag, value in opts:
        argv += [flag] + ([] if value is None else [value])
    _run_cli(argv, capsys)


def test_the_stubs_let_valid_commands_through(stubs, capsys):
    """The fuzz above is only worth something if valid option sets reach the (stubbed) work."""
    assert main(["bench", "track", "--smoke", "--methods", "ecc", "--out", str(stubs / "a")]) == 0
    assert main(["bench", "servo", "--seeds", "3", "4", "--out", str(stubs / "b")]) == 0
    assert main(["bench", "track", "--imagery", "natural", "--sources", "fur", "--out", str(stubs / "c")]) == 0
    assert main(["run", "--scenario", "pause", "--steps", "3", "--json", str(stubs / "r.json")]) == 0
    assert main(["bench", "servo", "--suite", "occlusion-4dof-v2", "--methods", "ecc", "--out", str(stubs / "d")]) == 0
    cfg = SEEN_CONFIGS[-1]
    assert cfg.suite == "occlusion-4dof-v2" and cfg.tilt_deg == 0 and cfg.trackers == ("ecc",)  # yours alone
    assert cfg.episode_seeds == list(range(1000, 1020)) and cfg.camera == "phone_handheld"  # the test split
    assert json.loads((stubs / "d" / "summary.json").read_text())["split"] == "test"
    assert main(["bench", "servo", "--suite", "occlusion-4dof-v1", "--split", "dev", "--out", str(stubs / "g")]) == 0
    assert SEEN_CONFIGS[-1].episode_seeds == list(range(200, 220))  # a retired suite still runs on its old seeds
    assert main(["bench", "servo", "--suite", "quick", "--methods", "ecc", "--out", str(stubs / "f")]) == 0
    assert SEEN_CONFIGS[-1].trackers == ("ground_truth", "hybrid:homography", "ecc")  # quick: beside the references
    assert main(["bench", "track", "--suite", "track-occlusion-v2", "--out", str(stubs / "e")]) == 0
    assert SEEN_CONFIGS[-1].methods == ("hybrid", "deep_lk", "ecc") and SEEN_CONFIGS[-1].mounts == ("handheld",)
    assert main(["scene", "--frames", "2", "--out", str(stubs / "s")]) == 0
    assert "NOT a result" in capsys.readouterr().out


def test_bench_seeds_come_from_a_split_or_a_fresh_draw(stubs, capsys):
    """Without seeds a benchmark runs its test split; --split dev the tuning seeds; --fresh N seeds drawn from the
    system's entropy, recorded as such; seeds named two ways are refused."""
    def summary(name):
        return json.loads((stubs / name / "summary.json").read_text())

    assert main(["bench", "servo", "--out", str(stubs / "a")]) == 0
    assert SEEN_CONFIGS[-1].episode_seeds == list(range(1000, 1020)) and summary("a")["split"] == "test"
    assert "Seeds" not in capsys.readouterr().err
    assert main(["bench", "servo", "--split", "dev", "--episodes", "3", "--out", str(stubs / "b")]) == 0
    assert SEEN_CONFIGS[-1].episode_seeds == [200, 201, 202] and summary("b")["split"] == "dev"
    assert main(["bench", "track", "--fresh", "2", "--out", str(stubs / "c")]) == 0
    seeds = SEEN_CONFIGS[-1].seeds
    assert len(seeds) == 2 and min(seeds) >= 10_000 and summary("c")["seeds_fresh"] is True
    assert summary("c")["seeds"] == list(seeds) and summary("c")["split"] == "fresh"
    assert main(["bench", "track", "--fresh", "2", "--out", str(stubs / "d")]) == 0
    assert SEEN_CONFIGS[-1].seeds != seeds  # drawn anew
    assert main(["bench", "track", "--imagery", "natural", "--out", str(stubs / "e")]) == 0
    assert SEEN_CONFIGS[-1].seeds == (3000, 3001)
    assert main(["bench", "track", "--seeds", "101", "--out", str(stubs / "f")]) == 0
    assert summary("f")["split"] == "dev" and summary("f")["seeds_fresh"] is False
    capsys.readouterr()
    for argv, msg in ((["--seeds", "5", "--fresh", "2"], "both choose the seeds"),
                      (["--split", "dev", "--fresh", "2"], "both choose the seeds"),
                      (["--fresh", "0"], "--fresh takes a number of seeds from 1"),
                      (["--fresh", "3", "--episodes", "4"], "leave --episodes out")):
        assert main(["bench", "servo", *argv, "--out", str(stubs / "x")]) == 2
        assert msg in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ CLI, from the parsers

# The commands the property below draws from: those whose long work the stubs replace (a sweep's spec is replaced by
# a missing one). Every option of theirs is drawn, new ones too; a new command is drawn once it is listed here, as
# the others (train, dataset, budget, track, demo, results) would run real work: `results make` runs benchmarks.
FUZZED_COMMANDS = ("run", "scene", "scenes", "bench", "sweep")
UNFUZZED_OPTIONS = ("-h", "--help", "--version", "--spawn")
# a fixed seed keeps CI deterministic; HVS_FUZZ_EXAMPLES=2000 searches further by hand
TEXT_VALUES = ["", "x", "nope", "a,b", "-1", "0", "1", "nan", "inf", "1e9", "../x", "/etc/passwd:root", "{OUT}",
               "{OUT}/f.json", "mod:make", "hybrid", "walk_by", "key=value", "scale=abc", "0,0,0,0,0,0"]


def _parsers() -> dict:
    """The fuzzed commands' parsers, by name, as build_parser makes them."""
    import argparse

    from hvs_sim.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: p for name, p in sub.choices.items() if name in FUZZED_COMMANDS}


def _values(action) -> st.SearchStrategy:
    """A value (list of words) for an argparse action: its choices, or numbers and text of every kind."""
    if action.nargs == 0:
        return st.just([])
    if action.choices:
        word = st.sampled_from([*map(str, action.choices), "nope", ""])
    elif action.type is int:
        word = st.sampled_from(["0", "1", "3", "-2", "1e3", "x", "2.5", "99999999999"])
    elif action.type is float:
        word = st.sampled_from(["0", "0.5", "-1", "nan", "inf", "1e300", "x", ""])
    else:
        word = st.sampled_from(TEXT_VALUES)
    if action.nargs in ("+", "*") or isinstance(action.nargs, int):
        n = action.nargs if isinstance(action.nargs, int) else None
        return st.lists(word, min_size=n or (1 if action.nargs == "+" else 0), max_size=n or 3)
    return word.map(lambda w: [w])


@settings(max_examples=int(os.environ.get("HVS_FUZZ_EXAMPLES", "100")), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_cli_argument_vectors_drawn_from_the_parsers(stubs, capsys, monkeypatch, data):
    """Any argument vector the parsers can be handed: success, or exit 2 with one line saying why; never a traceback.
    The vectors come from the parsers' own actions, so a new option is fuzzed without being listed here."""
    import tempfile

    monkeypatch.chdir(stubs)  # defaults such as out/scene land in the test's folder
    parsers = _parsers()
    command = data.draw(st.sampled_from(sorted(parsers)), label="command")
    parser = parsers[command]
    argv = [command]
    for action in parser._actions:
        if not action.option_strings and action.dest != "help":  # positionals, in order
            argv += data.draw(_values(action), label=action.dest)
    options = [a for a in parser._actions if a.option_strings and not set(a.option_strings) & set(UNFUZZED_OPTIONS)]
    for action in data.draw(st.lists(st.sampled_from(options), max_size=4, unique_by=id), label="options"):
        argv += [action.option_strings[-1], *data.draw(_values(action), label=action.dest)]
    out = tempfile.mkdtemp(dir=stubs)
    argv = [w.replace("{OUT}", out) for w in argv]
    if command == "sweep" and argv[1:2] != ["report"]:
        argv[1:2] = [str(Path(out) / "missing.toml")]  # a real spec would run real tasks
    code = main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err, (argv, err)
    assert code in (0, 2), (argv, code, err)
    if code == 2:
        lines = [line for line in err.splitlines() if "error:" in line]
        assert len(lines) == 1, (argv, err)  # one line says why (argparse's usage above it is not a second error)


def test_run_prints_the_pose_error_over_the_controlled_dofs(stubs, capsys):
    """`run` and `demo` print the pose error that convergence and error.png judge: over the controlled DOFs."""
    assert main(["run", "--scenario", "pause", "--steps", "3", "--json", str(stubs / "r.json")]) == 0
    printed = capsys.readouterr().out
    assert "final_controlled_pose_error_mm" in printed and "final_controlled_pose_error_deg" in printed
    assert '"final_pose_error_mm"' not in printed


def test_scenes_list_says_jpeg_off_rather_than_q0(capsys):
    assert main(["scenes", "--list"]) == 0
    printed = capsys.readouterr().out
    assert "JPEG off" in printed and "JPEG q0" not in printed and "JPEG q75" in printed
