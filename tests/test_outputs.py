"""The output layer (hvs_sim/outputs.py): a command never removes or replaces what hvs_sim did not write, never
writes through a link, and a full disk is a clear error naming the file, with no partial file left. Each case of
issue 53's independent sweep is a test here; the full disk is a fault-injection fixture (`full_disk`) that fails the
layer's writes with ENOSPC after N bytes."""

from __future__ import annotations

import contextlib
import errno
import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from hvs_sim import manifest, outputs
from hvs_sim.cli import main
from hvs_sim.errors import ConfigError, OutputError

SMALL = ["--width", "160", "--height", "120"]
SCENE = ["scene", "--frames", "3", *SMALL]
RUN = ["run", "--scenario", "clear", "--tracker", "ground_truth", "--steps", "3", "--width", "320", "--height", "240"]


def _fails(argv, capsys, *words, code: int = 2) -> str:
    assert main(argv) == code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for w in words:
        assert w in err, err
    return err


def _image(path: Path, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)  # a PNG whatever the name says
    path.write_bytes(cv2.imencode(".png", cv2.GaussianBlur(rng.integers(0, 255, (96, 128, 3), dtype=np.uint8),
                                                           (0, 0), 1.5))[1].tobytes())
    return path.read_bytes()


def _temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*") if ".tmp" in p.name]


class FullDisk:
    """A disk of `capacity` bytes under the layer: each write (ensure_space before a chunk, account after a library
    writer's file) uses it up, then fails as a full disk does."""

    def __init__(self, capacity: int):
        self.capacity, self.used = capacity, 0

    def _full(self, path):
        return OSError(errno.ENOSPC, "No space left on device", str(path))

    def ensure_space(self, path, need_bytes, native=True):
        if self.used + need_bytes > self.capacity:
            raise self._full(path)
        self.used += need_bytes

    def account(self, path, nbytes):
        self.used += nbytes
        if self.used > self.capacity:
            raise self._full(path)


@pytest.fixture
def full_disk(monkeypatch):
    def make(capacity: int) -> FullDisk:
        disk = FullDisk(capacity)
        monkeypatch.setattr(outputs, "ensure_space", disk.ensure_space)
        monkeypatch.setattr(outputs, "account", disk.account)
        return disk
    return make


# ------------------------------------------------------------------------- --overwrite never deletes an input


@pytest.mark.parametrize("name, fmt", [("preview.png", "mp4"), ("frames.mp4", "mp4"), ("ground_truth.npz", "png")])
def test_overwrite_refuses_an_input_named_as_an_output(tmp_path, capsys, name, fmt):
    d = tmp_path / "d"
    d.mkdir()
    before = _image(d / name)
    _fails([*SCENE, "--format", fmt, "--target-image", str(d / name), "--out", str(d), "--overwrite"], capsys,
           "is the input")
    assert (d / name).read_bytes() == before


@pytest.mark.parametrize("name", ["budget.png", "budget.md"])
def test_budget_refuses_an_input_named_as_its_output(tmp_path, capsys, name):
    o = tmp_path / "o"
    o.mkdir()
    before = _image(o / name)
    _fails(["budget", "--bound-only", "--target-image", str(o / name), "--out", str(o), "--overwrite"], capsys,
           "is the input")
    assert (o / name).read_bytes() == before


def test_wall_images_inside_out_are_never_removed(tmp_path, capsys):
    o = tmp_path / "o"
    (o / "frames").mkdir(parents=True)
    kept = {p: _image(p, i) for i, p in enumerate(o / "frames" / f"wall{i:02d}.png" for i in range(12))}
    _fails([*SCENE, "--format", "png", "--wall-images", str(o / "frames"), "--out", str(o), "--overwrite"], capsys,
           "lies inside the input")
    assert main([*SCENE, "--wall-images", str(o / "frames"), "--out", str(o), "--overwrite"]) == 0  # mp4 beside them
    assert all(p.read_bytes() == b for p, b in kept.items())
    assert (o / "frames.mp4").is_file()


def test_overwrite_removes_only_what_hvs_sim_wrote_and_never_through_a_link(tmp_path, capsys):
    o = tmp_path / "o"
    assert main([*SCENE, "--format", "png", "--out", str(o)]) == 0
    assert manifest.manifest_files(o / "frames") == {"00000.png", "00001.png", "00002.png"}
    (o / "frames" / "9999.png").write_bytes(b"mine")  # the user's, named like a frame
    (o / "notes.txt").write_text("mine")
    assert main([*SCENE[:1], "--frames", "2", *SMALL, "--format", "png", "--out", str(o), "--overwrite"]) == 0
    assert sorted(p.name for p in (o / "frames").glob("*.png")) == ["00000.png", "00001.png", "9999.png"]
    assert (o / "frames" / "9999.png").read_bytes() == b"mine" and (o / "notes.txt").read_text() == "mine"
    # frames/ a link to a folder outside --out: refused, nothing there removed or written
    precious = tmp_path / "precious"
    precious.mkdir()
    kept = _image(precious / "00000.png")
    link = tmp_path / "p"
    link.mkdir()
    (link / "frames").symlink_to(precious)
    (link / ".hvs_sim-outputs").write_text(json.dumps({"files": ["frames"]}))
    (precious / ".hvs_sim-outputs").write_text(json.dumps({"files": ["00000.png"]}))  # even one that claims it
    _fails([*SCENE, "--format", "png", "--out", str(link), "--overwrite"], capsys, "symbolic link")
    assert (precious / "00000.png").read_bytes() == kept and sorted(p.name for p in precious.iterdir()) == [
        ".hvs_sim-outputs", "00000.png"]
    manifest.clear_written(link)  # the layer itself: a link is never followed when clearing
    assert (precious / "00000.png").read_bytes() == kept


def test_a_manifest_entry_that_leaves_the_folder_is_ignored(tmp_path):
    (tmp_path / "o").mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (tmp_path / "o" / ".hvs_sim-outputs").write_text(json.dumps({"files": ["../victim.txt", "/etc/passwd"]}))
    assert manifest.clear_written(tmp_path / "o") == [] and victim.read_text() == "keep"


# ------------------------------------------------------------------------- sidecars are not replaced unasked


def test_run_refuses_to_replace_a_sidecar_it_did_not_write(tmp_path, capsys):
    (tmp_path / "r_steps.csv").write_text("mine")
    _fails([*RUN, "--json", str(tmp_path / "r.json")], capsys, "r_steps.csv exists and was not written by hvs_sim")
    assert (tmp_path / "r_steps.csv").read_text() == "mine" and not (tmp_path / "r.json").exists()
    (tmp_path / "r_steps.csv").unlink()
    (tmp_path / "elsewhere.csv").write_text("mine")
    (tmp_path / "r_steps.csv").symlink_to(tmp_path / "elsewhere.csv")
    _fails([*RUN, "--json", str(tmp_path / "r.json")], capsys, "symbolic link")
    assert (tmp_path / "elsewhere.csv").read_text() == "mine"
    (tmp_path / "r_steps.csv").unlink()
    assert main([*RUN, "--json", str(tmp_path / "r.json")]) == 0
    assert main([*RUN, "--json", str(tmp_path / "r.json")]) == 0  # its own sidecar: replaced
    assert len((tmp_path / "r_steps.csv").read_text().splitlines()) == 4


def test_run_figures_and_demo_refuse_files_they_did_not_write(tmp_path, capsys):
    fig = tmp_path / "fig"
    fig.mkdir()
    (fig / "frames.png").write_bytes(b"mine")
    _fails([*RUN, "--figures", str(fig)], capsys, "frames.png exists and was not written by hvs_sim")
    assert (fig / "frames.png").read_bytes() == b"mine"
    for name in ("run.json", "frames.png"):
        o = tmp_path / f"demo_{name}"
        o.mkdir()
        (o / name).write_text("mine")
        _fails(["demo", "--out", str(o)], capsys, f"{name} exists and was not written by hvs_sim", "--overwrite")
        assert (o / name).read_text() == "mine"


def test_sweep_refuses_a_folder_that_is_not_a_sweeps(tmp_path, capsys, monkeypatch):
    spec = tmp_path / "s.toml"
    spec.write_text('kind = "servo"\n[axes]\ntracker = ["ground_truth"]\n[fixed]\nsteps = 2\nscenario = "clear"\n'
                    'camera = "ideal"\n')
    o = tmp_path / "o"
    o.mkdir()
    (o / "results.csv").write_text("mine")
    _fails(["sweep", str(spec), "--out", str(o)], capsys, "not a sweep folder", "results.csv")
    assert (o / "results.csv").read_text() == "mine" and sorted(p.name for p in o.iterdir()) == ["results.csv"]
    monkeypatch.chdir(o)
    _fails(["sweep", str(spec), "--out", "."], capsys, "not a sweep folder")
    t = tmp_path / "t"
    t.mkdir()
    (t / "tasks").write_text("a file")
    _fails(["sweep", str(spec), "--out", str(t)], capsys, "tasks is a file")


# ------------------------------------------------------------------------- paths refused before any work


def test_outputs_that_cannot_be_written_are_refused_before_the_run(tmp_path, capsys):
    long_json = tmp_path / ("r" * 300 + ".json")
    _fails([*RUN, "--json", str(long_json)], capsys, "file name is too long")
    _fails([*SCENE, "--out", ""], capsys, "--out is empty")
    _fails([*SCENE, "--out", str(tmp_path / "o"), "--mcap", str(tmp_path / "o")], capsys, "would lie inside")
    assert not (tmp_path / "o").exists()
    _fails([*RUN, "--figures", ""], capsys, "--figures is empty")
    _fails([*RUN, "--json", ""], capsys, "--json is empty")


@pytest.fixture
def video(tmp_path) -> Path:
    from hvs_sim.videoio import Mp4Writer

    rng = np.random.default_rng(1)
    frame = cv2.GaussianBlur(rng.integers(0, 255, (120, 160, 3), dtype=np.uint8), (0, 0), 2)
    path = tmp_path / "clip.mp4"
    w = Mp4Writer(path, 30, (160, 120))
    for k in range(4):
        w.write(np.roll(frame, k, axis=1))
    w.close()
    return path


def test_track_refuses_its_out_as_the_bag_an_empty_out_and_a_link_loop(tmp_path, capsys, video):
    o = tmp_path / "o"
    _fails(["track", str(video), "--roi", "40,30,60,50", "--tracker", "ecc", "--out", str(o), "--mcap", str(o)],
           capsys, "would lie inside")
    assert not o.exists()
    _fails(["track", str(video), "--roi", "40,30,60,50", "--tracker", "ecc", "--out", ""], capsys, "--out is empty")
    loop = tmp_path / "loop.mp4"
    loop.symlink_to(loop)
    _fails(["track", str(loop), "--roi", "40,30,60,50", "--out", str(tmp_path / "o2")], capsys, "link loop")


# ------------------------------------------------------------------------- a full disk, every writer


def _no_partial(folder: Path) -> None:
    assert _temporaries(folder) == [], _temporaries(folder)


@pytest.mark.parametrize("errno_, words", [(errno.ENOSPC, "No space left"), (errno.EROFS, "Read-only"),
                                           (errno.ENAMETOOLONG, "too long"), (errno.EACCES, "Permission denied")])
def test_the_layer_maps_write_failures_to_output_errors_and_keeps_the_old_file(tmp_path, monkeypatch, errno_, words):
    target = tmp_path / "summary.json"
    target.write_text("old")

    def refuse(src, dst):
        raise OSError(errno_, os.strerror(errno_), str(dst))

    monkeypatch.setattr(os, "replace", refuse)
    for write in (lambda: outputs.write_atomic(target, "new"),
                  lambda: outputs.write_with(target, lambda tmp: Path(tmp).write_text("new")),
                  lambda: outputs.write_image(target.with_suffix(".png"), np.zeros((8, 8, 3), np.uint8))):
        with pytest.raises(OutputError, match=words):
            write()
    assert target.read_text() == "old"
    _no_partial(tmp_path)


def test_a_library_writer_that_fails_quietly_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match=r"could not write .*x\.png"):
        outputs.write_with(tmp_path / "x.png", lambda tmp: False)
    _no_partial(tmp_path)


def test_run_onto_a_full_disk_names_the_file_and_leaves_no_partial_csv(tmp_path, capsys, full_disk):
    full_disk(300)  # the steps CSV's header and a row, not three
    err = _fails([*RUN, "--json", str(tmp_path / "r.json")], capsys, "r_steps.csv", "No space left")
    assert "no output of this command is complete" in err
    _no_partial(tmp_path)
    assert not (tmp_path / "r_steps.csv").exists() and not (tmp_path / "r.json").exists()


def test_run_figures_onto_a_full_disk(tmp_path, capsys, full_disk):
    full_disk(1000)
    _fails([*RUN, "--figures", str(tmp_path / "fig")], capsys, "frames.png", "No space left")
    _no_partial(tmp_path)


def test_run_mcap_onto_a_full_disk(tmp_path, capsys, full_disk):
    full_disk(20_000)
    _fails([*RUN, "--mcap", str(tmp_path / "bag")], capsys, "bag", "No space left")
    assert not (tmp_path / "bag").exists()
    _no_partial(tmp_path)


def test_scene_mp4_onto_a_full_disk(tmp_path, capsys, full_disk):
    full_disk(100_000)  # one 160×120 frame is 57.6 kB raw: the second does not fit
    _fails([*SCENE, "--out", str(tmp_path / "o")], capsys, "frames.mp4", "No space left")
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == []
    _no_partial(tmp_path)


def test_scene_png_onto_a_full_disk_leaves_only_whole_frames(tmp_path, capsys, full_disk):
    assert main([*SCENE, "--format", "png", "--out", str(tmp_path / "sized")]) == 0  # the frames' sizes (deterministic)
    sizes = [p.stat().st_size for p in sorted((tmp_path / "sized" / "frames").glob("*.png"))]
    full_disk(sizes[0] + sizes[1] // 2)  # the first frame fits, the second does not
    err = _fails([*SCENE, "--format", "png", "--out", str(tmp_path / "o")], capsys, "No space left", "written whole")
    frames = sorted((tmp_path / "o" / "frames").glob("*.png"))
    assert [p.name for p in frames] == ["00000.png"] and cv2.imread(str(frames[0])) is not None  # none truncated
    assert "frames 0 to 0 are written whole" in err and "could not write" in err and "00001.png" in err
    _no_partial(tmp_path)


def test_track_video_onto_a_full_disk(tmp_path, capsys, full_disk, video):
    full_disk(100_000)
    o = tmp_path / "o"
    _fails(["track", str(video), "--roi", "40,30,60,50", "--tracker", "ecc", "--out", str(o)], capsys,
           "annotated.mp4", "No space left")
    assert list(o.iterdir()) == []
    _no_partial(tmp_path)


def test_track_csv_onto_a_full_disk(tmp_path, capsys, full_disk, monkeypatch, video):
    from hvs_sim import videoio

    monkeypatch.setattr(videoio.Mp4Writer, "write", lambda self, rgb: None)  # the CSV meets the full disk first
    full_disk(200)
    _fails(["track", str(video), "--roi", "40,30,60,50", "--tracker", "ecc", "--out", str(tmp_path / "o")], capsys,
           "track.csv", "No space left")
    assert list((tmp_path / "o").iterdir()) == []
    _no_partial(tmp_path)


def test_bench_and_sweep_report_onto_a_full_disk(tmp_path, capsys, full_disk, monkeypatch):
    from hvs_sim.bench import track
    from hvs_sim.sweep import parse_spec, report, run_sweep

    def bench(cfg, out, progress=True, resume=False):  # the benchmark's own work, stubbed: its summary is what is rewritten
        outputs.write_atomic(Path(out) / "summary.json", "{}")
        return {"occlusion_scenarios": {}, "target_set": {}}

    monkeypatch.setattr(track, "run_track_bench", bench)
    spec = parse_spec('kind = "servo"\n[axes]\nseed = [1]\n[fixed]\ntracker = "ground_truth"\nsteps = 2\n'
                      'scenario = "clear"\ncamera = "ideal"\n')
    run_sweep(spec, tmp_path / "sw", progress=False)
    disk = full_disk(10)
    disk.used = disk.capacity  # full from here on
    _fails(["bench", "track", "--smoke", "--out", str(tmp_path / "b")], capsys, "summary.json", "No space left")
    with pytest.raises(OutputError, match=r"report\.md .No space left"):
        report(tmp_path / "sw", ["seed"])
    _no_partial(tmp_path)


def test_budget_figure_onto_a_full_disk(tmp_path, capsys, full_disk):
    full_disk(2_000)
    _fails(["budget", "--bound-only", "--out", str(tmp_path / "o")], capsys, "budget.png", "No space left")
    _no_partial(tmp_path)


def test_sweep_lock_onto_a_full_disk(tmp_path, capsys, monkeypatch):
    from hvs_sim import sweep
    from hvs_sim.sweep import run as sweep_run

    class Full:
        def __init__(self, *a, **k):
            pass

        def fileno(self):
            return os.open(os.devnull, os.O_RDONLY)

        def seek(self, *a):
            pass

        truncate = read = seek

        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

        def close(self):
            pass

    monkeypatch.setattr(sweep_run, "open", Full, raising=False)  # the lock's (sweep/run.py)
    spec = sweep.parse_spec('kind = "servo"\n[axes]\ntracker = ["ground_truth"]\n')
    with pytest.raises(OutputError, match=r"\.sweep\.lock .No space left"):
        sweep.run_sweep(spec, tmp_path / "o", progress=False)


def test_a_figure_onto_a_full_disk(tmp_path, full_disk):
    """Every figure (run's, the benchmarks', budget's, a sweep report's) is written by save_figure."""
    import matplotlib.pyplot as plt

    fig = plt.figure()
    (tmp_path / "fig.png").write_bytes(b"old")
    full_disk(100)
    with pytest.raises(OutputError, match=r"fig\.png .No space left"):
        outputs.save_figure(fig, tmp_path / "fig.png")
    plt.close(fig)
    assert (tmp_path / "fig.png").read_bytes() == b"old"
    _no_partial(tmp_path)


def test_an_interrupted_scene_keeps_the_frames_it_rendered(tmp_path, monkeypatch):
    """SIGTERM or Ctrl-C in a render: what was finished is kept, as the message says, marked interrupted."""
    from hvs_sim.render import sequence
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    scenario = make_scenario("walk_by", camera=CameraConfig(width=160, height=120))
    real = sequence.iterate_sequence

    def two_then_stop(*a, **k):  # the third frame's render is interrupted
        frames = real(*a, **k)
        yield next(frames)
        yield next(frames)
        raise KeyboardInterrupt

    monkeypatch.setattr(sequence, "iterate_sequence", two_then_stop)
    for fmt in ("mp4", "png"):
        out = tmp_path / fmt
        with pytest.raises(KeyboardInterrupt):
            sequence.write_sequence(scenario, out, fmt=fmt, n_frames=5, progress=False)
        meta = json.loads((out / "scenario.json").read_text())
        assert meta["interrupted"] is True and meta["frames"] == 2
        assert len((out / "ground_truth.csv").read_text().splitlines()) == 3
        if fmt == "mp4":
            assert int(cv2.VideoCapture(str(out / "frames.mp4")).get(cv2.CAP_PROP_FRAME_COUNT)) == 2
        else:
            assert sorted(p.name for p in (out / "frames").glob("*.png")) == ["00000.png", "00001.png"]
        _no_partial(out)


def test_an_unwrapped_write_error_is_still_one_line(tmp_path, capsys, monkeypatch):
    """A writer outside the layer (a library's own file) that hits a full disk: no traceback, the temporaries go."""
    from hvs_sim.cli import scene

    def boom(*a, **k):
        tmp = outputs.temporary_beside(tmp_path / "o" / "x.bin")
        tmp.write_text("partial")
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp))

    monkeypatch.setattr(scene, "_write", boom)
    _fails([*SCENE, "--out", str(tmp_path / "o")], capsys, "No space left on device")
    _no_partial(tmp_path)


def test_a_benchmark_out_with_a_link_among_its_outputs_is_refused(tmp_path):
    out = tmp_path / "bench"
    out.mkdir()
    (tmp_path / "elsewhere.json").write_text("mine")
    (out / "summary.json").symlink_to(tmp_path / "elsewhere.json")
    with pytest.raises(ConfigError, match="summary.json .*symbolic link"):
        outputs.fresh_out_dir(out, True, ("summary.json", "table.md", "*.png"))
    assert (tmp_path / "elsewhere.json").read_text() == "mine"


def test_check_replaceable_and_check_apart_directly(tmp_path):
    (tmp_path / "a").write_text("x")
    with pytest.raises(ConfigError, match="not written by hvs_sim"):
        outputs.check_replaceable({"a": tmp_path / "a"})
    manifest.record([tmp_path / "a"])
    outputs.check_replaceable({"a": tmp_path / "a"})  # now hvs_sim's
    with pytest.raises(ConfigError, match="one file"):
        outputs.check_apart([], {"x": tmp_path / "a", "y": tmp_path / "a"})


def test_dataset_onto_a_full_disk_is_refused_before_hdf5_writes(tmp_path, capsys, full_disk):
    """HDF5 segfaults on a disk that fills under it: the layer refuses first, and nothing is left in --out."""
    full_disk(1_000)
    _fails(["dataset", "--episodes", "1", "--max-steps", "3", "--out", str(tmp_path / "d")], capsys,
           "could not write the dataset", "No space left")
    assert [p.name for p in (tmp_path / "d").iterdir()] == []


# ------------------------------------------------------------------------- a real small disk, where one can be mounted


@pytest.fixture
def small_disk(tmp_path):
    """A 512 kB tmpfs (root only: skipped elsewhere), unmounted after the test."""
    import subprocess

    where = tmp_path / "small"
    where.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", str(where)],
                                           capture_output=True, check=False).returncode:
        pytest.skip("no small tmpfs here (mounting one needs root)")
    yield where
    subprocess.run(["umount", "-l", str(where)], capture_output=True, check=False)


def _fill(disk: Path, leave: int = 0) -> None:
    """Fill the disk to the last `leave` bytes."""
    with open(disk / "filler", "wb", buffering=0) as f, contextlib.suppress(OSError):
        while True:
            f.write(b"\0" * 4096)
    if leave:
        size = (disk / "filler").stat().st_size
        os.truncate(disk / "filler", max(0, size - leave))


def _cli(*argv) -> tuple[int, str]:
    """hvs-sim in its own process: a native crash (a segfault) shows as a negative exit code, not a dead test run."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "hvs_sim.cli", *map(str, argv)], capture_output=True, text=True,
                          timeout=300, check=False, env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})
    return done.returncode, done.stderr


def test_every_writer_onto_a_real_full_disk_says_so_and_leaves_no_partial_file(small_disk, video):
    _fill(small_disk, leave=120_000)  # room for a few PNG frames, not 40
    code, err = _cli("scene", *SMALL, "--frames", "40", "--format", "png", "--out", small_disk / "s")
    assert code == 2 and "No space left" in err and "Traceback" not in err, err
    assert all(cv2.imread(str(p)) is not None for p in (small_disk / "s" / "frames").glob("*.png"))
    _fill(small_disk)
    for argv in ([*RUN, "--json", small_disk / "r.json"], ["scene", *SMALL, "--frames", "3", "--out", small_disk / "m"],
                 ["track", video, "--roi", "40,30,60,50", "--tracker", "ecc", "--out", small_disk / "t"],
                 ["dataset", "--episodes", "1", "--max-steps", "3", "--out", small_disk / "d"]):
        code, err = _cli(*argv)
        assert code == 2 and "Traceback" not in err and ("No space left" in err or "cannot write" in err), (argv, err)
        _no_partial(small_disk)
