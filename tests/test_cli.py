"""The CLI refuses what it cannot honour before any long work starts, and says so."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from hvs_sim.cli import build_parser, main
from hvs_sim.errors import InputError, StateError
from hvs_sim.manifest import record
from hvs_sim.outputs import fresh_out_dir
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop


def _fails(argv, capsys, *words) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err, err


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["--version"])
    assert exc.value.code == 0 and "hvs-sim" in capsys.readouterr().out


def test_run_has_no_mount_option_and_checks_its_outputs_first(tmp_path, capsys):
    _fails(["run", "--mount", "handheld", "--steps", "2"], capsys, "unrecognized arguments: --mount")
    _fails(["run", "--steps", "2", "--json", str(tmp_path)], capsys, "--json", "is a folder")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _fails(["run", "--steps", "2", "--rrd", str(blocker / "run.rrd")], capsys, "--rrd")
    _fails(["run", "--steps", "0"], capsys, "--steps must be >= 1")


def test_scene_refuses_zero_frames_and_a_non_empty_out(tmp_path, capsys):
    _fails(["scene", "--frames", "0", "--out", str(tmp_path / "a")], capsys, "--frames must be from 1 to")
    _fails(["scene", "--frames", "100000000", "--out", str(tmp_path / "a")], capsys, "--frames must be from 1 to 36000")
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "old.txt").write_text("x")
    _fails(["scene", "--frames", "1", "--out", str(tmp_path / "b")], capsys, "not empty", "--overwrite")


def test_bench_options_that_do_not_apply_are_refused(tmp_path, capsys):
    out = str(tmp_path / "o")
    _fails(["bench", "servo", "--mounts", "arm", "--out", out], capsys, "--mounts applies to `bench track` only")
    _fails(["bench", "track", "--episodes", "3", "--out", out], capsys, "--episodes applies to `bench servo` only")
    _fails(["bench", "servo", "--episodes", "0", "--out", out], capsys, "episodes must be an integer")
    _fails(["bench", "servo", "--episodes", "2", "--seeds", "1", "2", "--out", out], capsys, "not both")
    _fails(["bench", "track", "--smoke", "--methods", "hybird", "--out", out], capsys, "unknown tracker 'hybird'",
           "accepted")
    _fails(["bench", "track", "--smoke", "--scenarios", "nope", "--out", out], capsys, "unknown scenario 'nope'")


def test_bench_refuses_a_non_empty_out_and_overwrite_replaces_only_its_own_files(tmp_path, capsys):
    out = tmp_path / "bench"
    out.mkdir()
    (out / "fig7_walk_by.png").write_bytes(b"stale")
    (out / "notes.txt").write_text("mine")
    _fails(["bench", "track", "--smoke", "--out", str(out)], capsys, "not empty", "fig7_walk_by.png")
    fresh_out_dir(out, True, ("summary.json", "*.png"))  # no manifest: hvs_sim wrote none of them, none goes
    assert (out / "fig7_walk_by.png").read_bytes() == b"stale" and (out / "notes.txt").read_text() == "mine"
    record([out / "fig7_walk_by.png"])  # as an earlier benchmark writing it would have
    fresh_out_dir(out, True, ("summary.json", "*.png"))
    assert not (out / "fig7_walk_by.png").exists() and (out / "notes.txt").read_text() == "mine"


def test_train_writes_beside_the_package_weights_only_when_asked():
    args = build_parser().parse_args(["train", "gru"])
    assert args.out == "out/weights"


def test_closed_loop_stops_with_a_clear_error_when_the_tracker_cannot_start(monkeypatch):
    sc = make_scenario("clear", mount="arm", seed=0, camera=CameraConfig(width=160, height=120, fovy=45.0))
    loop = ServoLoop(sc, "deep_lk", LoopConfig(steps=3))

    def refuse(frame, roi):
        raise InputError("too little texture")

    monkeypatch.setattr(loop.tracker, "init", refuse)
    with pytest.raises(StateError, match="could not start on the first frame.*too little texture"):
        list(loop)


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signalled_run_stops_cleanly_and_keeps_a_summary_marked_interrupted(tmp_path, sig, code):
    from hvs_sim.servo.config import MAX_STEPS  # a run that cannot end before the signal, however loaded the machine

    out_json, out_rrd = tmp_path / "run.json", tmp_path / "run.rrd"
    cmd = [sys.executable, "-m", "hvs_sim.cli", "run", "--scenario", "clear", "--steps", str(MAX_STEPS), "--tracker",
           "ground_truth", "--width", "320", "--height", "240", "--json", str(out_json), "--rrd", str(out_rrd)]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.PIPE, env={**os.environ, "MUJOCO_GL": "egl"})
    seen, buf = 0, b""
    deadline = time.monotonic() + 240
    while seen < 5 and time.monotonic() < deadline:  # wait for a few steps on the progress bar
        chunk = proc.stderr.read1(256)
        if not chunk:
            break
        buf += chunk
        counts = re.findall(rb"(\d+)/" + str(MAX_STEPS).encode(), buf)
        seen = int(counts[-1]) if counts else 0
    assert seen >= 5, buf.decode(errors="replace")[-2000:]
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err.decode(errors="replace")[-2000:]
    assert "Traceback" not in err.decode(errors="replace")
    summary = json.loads(out_json.read_text())
    assert summary["interrupted"] is True and 5 <= summary["steps_run"] < MAX_STEPS
    assert out_rrd.stat().st_size > 0


def test_spawn_without_a_display_says_what_to_do_instead(monkeypatch, capsys):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    _fails(["run", "--steps", "2", "--spawn"], capsys, "no display", "--rrd")


@pytest.mark.parametrize("command", ["scene", "run", "bench", "train", "demo", "track"])
def test_help_shows_defaults(command, capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args([command, "--help"])
    text = capsys.readouterr().out
    assert "default" in text
    if command == "bench":
        assert "hybrid_paper" in text and "two_people" in text  # the named variants and scenarios are listed


def test_run_writes_its_figures(tmp_path, capsys):
    out = tmp_path / "figs"
    assert main(["run", "--scenario", "clear", "--tracker", "ground_truth", "--steps", "3", "--width", "320",
                 "--height", "240", "--figures", str(out)]) == 0
    assert (out / "frames.png").stat().st_size > 10_000 and (out / "error.png").stat().st_size > 10_000
    assert "figures:" in capsys.readouterr().out


def test_tracker_settings_from_the_command_line(tmp_path, capsys):
    _fails(["run", "--steps", "2", "--set", "occlusion_gat=0.3"], capsys, "accepted", "occlusion_gate")
    _fails(["run", "--steps", "2", "--set", "novalue"], capsys, "KEY=VALUE")
    _fails(["run", "--steps", "2", "--tracker", "ground_truth", "--set", "scale=1"], capsys, "no tracker settings")
    _fails(["run", "--steps", "2", "--tracker", "hybrid_residual", "--set",
            f"residual_weights={tmp_path / 'missing.pt'}"], capsys, "missing.pt")
    out = tmp_path / "r.json"
    assert main(["run", "--scenario", "clear", "--steps", "3", "--width", "320", "--height", "240", "--tracker",
                 "hybrid", "--set", "predictor=constant_velocity", "--set", "occlusion_gate=0.4", "--json",
                 str(out)]) == 0
    assert json.loads(out.read_text())["steps_run"] == 3


def test_run_refuses_two_outputs_in_one_file(tmp_path, capsys):
    from hvs_sim.cli import main

    same = tmp_path / "x.json"
    assert main(["run", "--steps", "2", "--json", str(same), "--rrd", str(same)]) == 2
    assert "one file" in capsys.readouterr().err and not same.exists()
    assert main(["run", "--steps", "2", "--json", str(tmp_path / "r.json"), "--rrd",
                 str(tmp_path / "r_steps.csv")]) == 2
    assert "one file" in capsys.readouterr().err


def test_a_run_that_fails_leaves_nothing_behind(tmp_path, capsys):
    """A tracker whose init fails stops the run: no run.json, no steps CSV, no recording, no temporary."""
    from hvs_sim.cli import main

    bad = tmp_path / "bad_tracker.py"
    bad.write_text("class T:\n    warp = 'similarity'\n    def init(self, frame, roi):\n        raise RuntimeError('no')\n"
                   "    def update(self, frame):\n        return None\n\ndef make():\n    return T()\n")
    out = tmp_path / "out"
    out.mkdir()
    assert main(["run", "--tracker", f"{bad}:make", "--steps", "3", "--width", "320", "--height", "240",
                 "--json", str(out / "run.json"), "--rrd", str(out / "run.rrd")]) == 2
    assert "could not start" in capsys.readouterr().err
    assert list(out.iterdir()) == []


def test_blur_made_from_the_motion_field_from_the_command_line(tmp_path, capsys, monkeypatch):
    """--blur field reaches the renderer; where it cannot apply it is refused, never ignored."""
    from hvs_sim.render.renderer import Renderer

    used = []
    rgb = Renderer.rgb
    monkeypatch.setattr(Renderer, "rgb", lambda self: used.append(self.sensor.blur) or rgb(self))
    assert main(["scene", "--scenario", "walk_by", "--frames", "3", "--width", "160", "--height", "120",
                 "--camera", "low_light", "--blur", "field", "--format", "png", "--out", str(tmp_path / "f")]) == 0
    assert used and set(used) == {"field"}
    _fails(["run", "--steps", "2", "--blur", "field"], capsys, "no exposure time", "phone_handheld")
    kept = tmp_path / "kept"  # refused before the output folder is touched, --overwrite or not
    kept.mkdir()
    (kept / "summary.json").write_text("{}")
    _fails(["bench", "servo", "--camera", "ideal", "--blur", "field", "--out", str(kept), "--overwrite"], capsys,
           "no exposure time")
    assert (kept / "summary.json").read_text() == "{}"
    _fails(["bench", "servo", "--suite", "occlusion-v1", "--blur", "field", "--out", str(tmp_path / "s")], capsys,
           "--blur changes what suite")
    _fails(["bench", "track", "--imagery", "natural", "--blur", "field", "--out", str(tmp_path / "n")], capsys,
           "natural imagery")
