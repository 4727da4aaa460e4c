"""Inputs an independent sweep found hanging, crashing with a traceback or silently accepted (issue 53), each now a
clear refusal: weights that are FIFOs or pickles, plugins that hang, exit or are not Python, tracker settings of the
wrong type, truncated images, damaged sweep records, abbreviated options, SIGTERM named as SIGTERM, and gymnasium's
AsyncVectorEnv under both start methods."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from hvs_sim import plugins
from hvs_sim.cli import main
from hvs_sim.errors import ConfigError, HvsError, WeightsError

SMALL = ["--width", "160", "--height", "120"]


def _fails(argv, capsys, *words) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("hvs-sim: error:") == 1, err
    for w in words:
        assert w in err, err
    return err


# ------------------------------------------------------------------------- weights


@pytest.mark.parametrize("setting", ["gru_weights", "residual_weights", "weights"])
def test_a_fifo_as_weights_is_refused_not_read(tmp_path, setting):
    """Opening a FIFO for reading blocks until a writer comes: it is refused before it is opened."""
    from hvs_sim.tracking import make_tracker

    fifo = tmp_path / ("w.npz" if setting == "weights" else "w.pt")
    os.mkfifo(fifo)
    extra = {"residual": True} if setting == "residual_weights" else {}
    with pytest.raises(WeightsError, match="named pipe"):
        make_tracker("hybrid", **{setting: str(fifo)}, **extra)


def test_a_fifo_as_weights_from_the_command_line(tmp_path, capsys):
    os.mkfifo(tmp_path / "gru.pt")
    _fails(["run", "--tracker", "hybrid", "--steps", "1", *SMALL, "--set", f"gru_weights={tmp_path / 'gru.pt'}"],
           capsys, "named pipe", "gru.pt")


class _Marker:
    """Unpickling this runs code (touches a file): a weights loader must never do it."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (Path.touch, (Path(self.path),))


def test_hostile_weights_are_refused_and_nothing_in_them_runs(tmp_path):
    import torch

    from hvs_sim.tracking import make_tracker

    marker = tmp_path / "ran"
    evil_npz = tmp_path / "evil.npz"
    np.savez(evil_npz, conv1_1_w=np.array([_Marker(marker)], dtype=object), conv1_1_b=np.zeros(64))
    with pytest.raises(WeightsError, match="not a readable .npz.*pickles"):
        make_tracker("hybrid", weights=str(evil_npz))
    evil_pt = tmp_path / "evil.pt"
    torch.save({"x": _Marker(marker)}, evil_pt)
    with pytest.raises(WeightsError, match="not a readable torch weights file"):
        make_tracker("hybrid", gru_weights=str(evil_pt))
    with pytest.raises(WeightsError, match="not a readable torch weights file"):
        make_tracker("hybrid", weights=str(evil_pt))
    assert not marker.exists()


# ------------------------------------------------------------------------- plugins


def _plugin(tmp_path: Path, body: str) -> str:
    path = tmp_path / f"plug_{abs(hash(body)) % 10**8}.py"
    path.write_text(textwrap.dedent(body))
    return f"{path}:make"


@pytest.mark.parametrize("body, words", [
    ("import sys\nsys.exit(0)\ndef make(**kw):\n    pass\n", ["failed to import", "sys.exit(0)"]),
    ("raise RuntimeError('boom')\n", ["failed to import", "RuntimeError: boom"]),
    ("import sys\ndef make(**kw):\n    sys.exit(3)\n", ["factory failed", "sys.exit(3)"]),
    ("def make(**kw):\n    raise ValueError('nope')\n", ["factory failed", "ValueError: nope"]),
    ("def make(**kw):\n    return 42\n", ["returned int, which lacks init, update"]),
])
def test_a_plugin_that_exits_raises_or_returns_garbage_is_an_error(tmp_path, capsys, body, words):
    _fails(["run", "--tracker", _plugin(tmp_path, body), "--steps", "1", *SMALL], capsys, *words)


def test_a_plugin_factory_that_hangs_is_stopped(tmp_path, monkeypatch):
    monkeypatch.setattr(plugins, "PLUGIN_TIMEOUT_S", 0.3)
    ref = _plugin(tmp_path, "import time\ndef make(**kw):\n    while True:\n        time.sleep(0.05)\n")
    with pytest.raises(plugins.PluginTimeout, match="did not return within 0.3 s"):
        plugins.build("tracker", ref)
    hang_import = _plugin(tmp_path, "import time\nwhile True:\n    time.sleep(0.05)\n")
    with pytest.raises(plugins.PluginTimeout, match="importing plugin file"):
        plugins.resolve("tracker", hang_import)


@pytest.mark.parametrize("ref", ["/etc/passwd:root", "plug/../../../../../../../etc/passwd:x"])
def test_a_file_that_is_not_python_is_refused_as_a_plugin(ref, capsys):
    _fails(["run", "--tracker", ref, "--steps", "1", *SMALL], capsys, "not a Python file")


def test_sigterm_is_named_as_sigterm(tmp_path, capsys, monkeypatch):
    """The handler's effect, raised where the command is (no real signal: nothing races)."""
    from hvs_sim.cli import track as track_command
    from hvs_sim.cli.common import _on_sigterm

    def terminated(*a, **k):
        _on_sigterm(15, None)

    monkeypatch.setattr(track_command, "track_footage", terminated)  # as `hvs-sim track` calls it
    assert main(["track", str(tmp_path / "clip.mp4"), "--roi", "1,1,40,40", "--out", str(tmp_path / "o")]) == 143
    err = capsys.readouterr().err
    assert "terminated (SIGTERM)" in err and "Ctrl-C" not in err
    monkeypatch.setattr("hvs_sim.cli.scene._write", terminated)
    assert main(["scene", "--frames", "1", *SMALL, "--out", str(tmp_path / "s")]) == 143
    assert "terminated (SIGTERM)" in capsys.readouterr().err


# ------------------------------------------------------------------------- settings and images


@pytest.mark.parametrize("value", ["abc", "nan", "true", '"0.5"', "[1]"])
def test_a_tracker_setting_of_the_wrong_type_is_named(capsys, value):
    _fails(["run", "--tracker", "hybrid", "--set", f"scale={value}", "--steps", "1", *SMALL], capsys,
           "scale must be a number")


def test_make_tracker_names_the_wrong_type_too():
    from hvs_sim.tracking import make_tracker

    with pytest.raises(ConfigError, match="match_threshold must be a number"):
        make_tracker("deep_lk", match_threshold="high")


def test_a_truncated_jpeg_is_refused_as_a_target(tmp_path, capsys):
    rng = np.random.default_rng(0)
    data = cv2.imencode(".jpg", cv2.GaussianBlur(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8), (0, 0), 2))[1]
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(data.tobytes()[: data.size // 2])
    _fails(["scene", "--frames", "1", *SMALL, "--target-image", str(cut), "--out", str(tmp_path / "o")], capsys,
           "truncated or damaged")
    assert not (tmp_path / "o").exists()


def test_options_must_be_written_in_full(capsys):
    _fails(["run", "--roi", "5", "--steps", "1"], capsys, "unrecognized arguments: --roi")
    _fails(["scene", "--frame", "5"], capsys, "unrecognized arguments: --frame")


# ------------------------------------------------------------------------- sweeps


def test_a_record_with_wrong_typed_metrics_is_not_done_and_report_says_what_it_left_out(tmp_path, capsys):
    from hvs_sim.sweep import load_spec, report, run_sweep

    spec_file = tmp_path / "s.toml"
    spec_file.write_text('kind = "servo"\n[axes]\nseed = [1, 2]\n[fixed]\ntracker = "ground_truth"\nsteps = 2\n'
                         'scenario = "clear"\ncamera = "ideal"\n')
    spec = load_spec(spec_file)
    out = tmp_path / "o"
    assert run_sweep(spec, out, progress=False)["ran"] == 2
    first, _ = sorted((out / "tasks").glob("*.json"))
    record = json.loads(first.read_text())
    record["metrics"].update(final_error_px="NaN-string", lost_steps=[1, 2])
    first.write_text(json.dumps(record))
    text = report(out, ["seed"], figures=False)
    assert "1 task record(s) unreadable or damaged, left out" in text and first.stem in text
    counts = run_sweep(spec, out, progress=False, retry_failed=False)
    assert counts["corrupt_rerun"] == 1  # not kept as done: set aside and run again
    table = (out / "results.csv").read_text()
    assert "NaN-string" not in table and "[1, 2]" not in table
    assert json.loads(first.read_text())["metrics"]["final_error_px"] != "NaN-string"


# ------------------------------------------------------------------------- gymnasium's vector env


VECTOR = """
import sys
import gymnasium as gym
import hvs_sim  # the parent only imports the package


def make():
    return gym.make("hvs_sim/VisualServo-v1", width=64, height=64)


if __name__ == "__main__":
    ctx = None if sys.argv[1] == "default" else sys.argv[1]
    envs = gym.vector.AsyncVectorEnv([make, make], context=ctx)
    envs.reset(seed=0)
    envs.step(envs.action_space.sample())
    envs.close()
    print("ok")
"""


@pytest.mark.parametrize("context", ["default", "spawn"])
def test_async_vector_env_runs_under_both_start_methods(tmp_path, context):
    """Without MUJOCO_GL, choosing the GL back-end once made a context in the parent, and a forked worker then hung
    for ever making its own; the probe now runs in a child process."""
    script = tmp_path / "vec.py"
    script.write_text(VECTOR)
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).resolve().parents[1]), env.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, str(script), context], env=env, capture_output=True, text=True, timeout=240,
                          check=False)
    assert done.returncode == 0 and done.stdout.strip().endswith("ok"), done.stderr[-2000:]


def test_every_refusal_here_is_an_hvs_error():
    assert issubclass(WeightsError, HvsError) and issubclass(plugins.PluginTimeout, HvsError)
