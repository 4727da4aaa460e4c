"""Sweeps: spec validation, the grid, resuming, failures recorded, local and Ray engines agreeing."""

from __future__ import annotations

import csv
import json

import pytest

from hvs_sim.cli import main
from hvs_sim.errors import ConfigError
from hvs_sim.sweep import TIMING_METRICS, parse_spec, report, run_sweep, task_id

TINY = """
kind = "track"
[axes]
tracker = ["ecc", "sift"]
seed = [100, 101]
width = [640, 96]          # 96 px wide: the target's ROI falls off the frame, so those tasks fail
[fixed]
scenario = "walk_by"
camera = "ideal"
frames = 4
"""


@pytest.mark.parametrize("text, words", [
    ('kind = "track"\n[axes]\ntrackr = ["ecc"]', "unknown key 'trackr'.*accepted: .*tracker"),
    ('kind = "track"\n[axes]\ntracker = ["kcf"]', "unknown tracker 'kcf'; accepted"),
    ('kind = "servo"\n[axes]\nmount = ["arm"]', "unknown key 'mount' for a servo sweep"),
    ('kind = "servo"\n[axes]\ngain = [1.0, -2.0]', "gain must be"),
    ('kind = "track"\n[axes]\nseed = []', "non-empty list"),
    ('kind = "track"\n[axes]\nseed = [1, 1]', "repeats"),
    ('kind = "track"\n[axes]\nseed = [1]\n[fixed]\nseed = 2', "both"),
    ('kind = "walk"\n[axes]\nseed = [1]', "unknown sweep kind 'walk'"),
    ('kind = "track"\n[axes]\nseed = [1.5]', "seed must be an integer"),
    ('kind = "track"\naxes = 3', "must be a table"),
    ('kind = "track"\n[axes\n', "not valid TOML"),
    ('kind = "track"\nextra = 1\n[axes]\nseed = [1]', "unknown top-level keys"),
    # values of the wrong type for the fields they set
    ('kind = "servo"\n[axes]\nevaluate = ["no"]\n', "evaluate must be True or False"),
    ('kind = "servo"\n[axes]\nhold_steps = [2.5]\n', "hold_steps must be an integer"),
    ('kind = "servo"\n[axes]\nconverge_px = [nan]\n', "converge_px must be a finite number"),
    ('kind = "servo"\n[axes]\ngain = [2, 2.0]\n', "repeats a value"),
])
def test_spec_errors_name_the_key_and_what_is_accepted(text, words):
    with pytest.raises(ConfigError, match=words):
        parse_spec(text)


def test_the_grid_is_the_product_of_the_axes_over_defaults_and_fixed():
    spec = parse_spec('kind = "servo"\n[axes]\ntracker = ["hybrid", "ecc"]\ngain = [1.0, 2.0, 4.0]\n'
                      '[fixed]\nscenario = "pause"\nsteps = 50')
    tasks = spec.tasks()
    assert len(tasks) == 6 and len({task_id("servo", t) for t in tasks}) == 6
    assert {(t["tracker"], t["gain"]) for t in tasks} == {(a, b) for a in ("hybrid", "ecc") for b in (1.0, 2.0, 4.0)}
    assert all(t["scenario"] == "pause" and t["steps"] == 50 and t["camera"] == "phone_handheld" for t in tasks)
    assert task_id("servo", tasks[0]) == task_id("servo", dict(reversed(list(tasks[0].items()))))  # order-free


def _table(out):
    """results.csv without the columns that measure time (they differ between runs)."""
    with open(out / "results.csv") as f:
        rows = list(csv.DictReader(f))
    drop = {*TIMING_METRICS, "engine"}
    return sorted(({k: v for k, v in r.items() if k not in drop} for r in rows), key=lambda r: r["id"])


@pytest.mark.slow
def test_failures_are_recorded_resume_skips_done_tasks_and_matches_an_uninterrupted_run(tmp_path):
    spec = parse_spec(TINY)
    full = run_sweep(spec, tmp_path / "full", workers=2, progress=False)
    assert full == {"tasks": 8, "skipped_done": 0, "ran": 8, "errors": 4, "retried_failed": 0, "corrupt_rerun": 0}
    rows = _table(tmp_path / "full")
    failed = [r for r in rows if r["status"] == "error"]
    assert len(failed) == 4 and all(r["width"] == "96" and "outside" in r["error"] for r in failed)
    assert all(float(r["pct_le_2px"]) == 100.0 for r in rows if r["status"] == "ok")
    again = run_sweep(spec, tmp_path / "full", progress=False, retry_failed=False)
    assert again["ran"] == 0 and again["skipped_done"] == 8
    again = run_sweep(spec, tmp_path / "full", progress=False)  # the failed tasks are tried again by default
    assert again["ran"] == again["retried_failed"] == again["errors"] == 4
    # an interrupted sweep: only some task files exist; re-running completes it to the same table
    part = tmp_path / "part"
    (part / "tasks").mkdir(parents=True)
    for f in sorted((tmp_path / "full" / "tasks").glob("*.json"))[:3]:
        (part / "tasks" / f.name).write_text(f.read_text())
    resumed = run_sweep(spec, part, progress=False, retry_failed=False)
    assert resumed["skipped_done"] == 3 and resumed["ran"] == 5
    assert _table(part) == rows
    text = report(tmp_path / "full", ["tracker"])
    assert "| ecc | 4 | 2 | 100.0 % |" in text and (tmp_path / "full" / "report.png").stat().st_size > 5_000


@pytest.mark.slow
def test_local_and_ray_engines_give_identical_metrics(tmp_path):
    pytest.importorskip("ray")
    spec = parse_spec(TINY.replace('width = [640, 96]', 'width = [640]'))
    run_sweep(spec, tmp_path / "local", engine="local", workers=1, progress=False)
    counts = run_sweep(spec, tmp_path / "ray", engine="ray", workers=2, progress=False)
    assert counts["ran"] == 4 and counts["errors"] == 0
    assert _table(tmp_path / "local") == _table(tmp_path / "ray")
    records = [json.loads(p.read_text()) for p in (tmp_path / "ray" / "tasks").glob("*.json")]
    assert {r["engine"] for r in records} == {"ray"}


def test_cli_checks_before_running(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('kind = "track"\n[axes]\nseed = [1]')
    assert main(["sweep", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")]) == 2
    assert main(["sweep", str(spec)]) == 2
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o"), "--address", "1.2.3.4:6379"]) == 2
    assert main(["sweep", "report", str(tmp_path / "o2"), "--by", "tracker"]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and "give --out" in err and "needs --engine ray" in err and "spec.json missing" in err


@pytest.mark.slow
def test_an_outside_tracker_and_law_run_on_ray_workers(tmp_path):
    pytest.importorskip("ray")
    spec = parse_spec('kind = "servo"\n[axes]\ntracker = ["hvs_test_plugins.track:make", "klt_homography"]\n'
                      'controller = ["plain_ibvs"]\n[fixed]\nsteps = 3\nscenario = "clear"\ncamera = "ideal"\n'
                      'template_from = "start"\n')
    counts = run_sweep(spec, tmp_path, engine="ray", workers=2, progress=False)
    assert counts["ran"] == 2 and counts["errors"] == 0, [p.read_text() for p in (tmp_path / "tasks").glob("*")]


def _tiny_spec():
    return parse_spec('kind = "servo"\n[axes]\ntracker = ["ground_truth"]\nseed = [200, 201]\n[fixed]\nsteps = 2\n'
                      'scenario = "clear"\ncamera = "ideal"\n')


def test_a_second_sweep_into_a_folder_in_use_is_refused(tmp_path):
    """Two processes: one holds the folder's lock (as a running sweep does), the other is refused and writes nothing."""
    import subprocess
    import sys
    import time

    from hvs_sim.sweep import LOCK_NAME

    holder = subprocess.Popen([sys.executable, "-c", (
        "import fcntl, os, sys, time; f = open(sys.argv[1], 'a+'); fcntl.flock(f, fcntl.LOCK_EX); "
        "f.write(f'pid {os.getpid()}'); f.flush(); print('held', flush=True); time.sleep(60)"),
        str(tmp_path / LOCK_NAME)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(ConfigError, match=f"another sweep is writing .*pid {holder.pid}"):
            run_sweep(_tiny_spec(), tmp_path, progress=False)
        assert not (tmp_path / "tasks").exists() and not (tmp_path / "spec.json").exists()
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.1)
    assert run_sweep(_tiny_spec(), tmp_path, progress=False)["ran"] == 2  # the lock died with its holder


def test_another_spec_is_refused_corrupt_records_rerun_and_failed_tasks_retried(tmp_path, capsys):
    spec = _tiny_spec()
    assert run_sweep(spec, tmp_path, progress=False)["ran"] == 2
    other = parse_spec('kind = "servo"\n[axes]\ntracker = ["ground_truth"]\nseed = [7]\n')
    with pytest.raises(ConfigError, match="holds another sweep's tasks"):
        run_sweep(other, tmp_path, progress=False)
    tasks = sorted((tmp_path / "tasks").glob("*.json"))
    tasks[0].write_text("")  # a record cut by a full disk
    record = json.loads(tasks[1].read_text())
    tasks[1].write_text(json.dumps({**record, "status": "error", "error": "RayActorError: node lost"}))
    assert "| ground_truth |" in report(tmp_path, ["tracker"], figures=False)  # the unreadable record is not fatal
    counts = run_sweep(spec, tmp_path, progress=False)
    assert counts["ran"] == 2 and counts["corrupt_rerun"] == 1 and counts["retried_failed"] == 1
    assert len(list((tmp_path / "tasks" / "corrupt").iterdir())) == 1
    assert all(json.loads(p.read_text())["status"] == "ok" for p in tasks)
    assert run_sweep(spec, tmp_path, progress=False)["ran"] == 0


def test_a_huge_grid_is_refused_before_it_is_built(tmp_path):
    axes = "\n".join(f"{k} = [{', '.join(str(200 + i) for i in range(40))}]" for k in ("seed",))
    spec = parse_spec(f'kind = "servo"\n[axes]\n{axes}\ngain = [{", ".join(str(1 + i / 10) for i in range(40))}]\n'
                      f'hold_steps = [{", ".join(str(i + 1) for i in range(10))}]\n')
    with pytest.raises(ConfigError, match="16000 tasks, more than 10000"):
        run_sweep(spec, tmp_path, progress=False)
    assert not (tmp_path / "spec.json").exists()


@pytest.mark.parametrize("axes, match", [
    ('template_from = ["start"]\ngoal_frames = [16, 32]', "goal_frames .16. averages"),
    ('tracker = ["ground_truth", "hybrid"]\nfeature_filter = [0.1]', "ground_truth.*feature_filter"),
    ('tracker = ["hybrid"]\ncontroller = ["dvs", "ibvs"]', "reads the images"),
])
def test_a_grid_cell_that_cannot_run_is_refused_before_anything_runs(tmp_path, axes, match):
    spec = parse_spec(f'kind = "servo"\n[axes]\n{axes}\n')
    with pytest.raises(ConfigError, match=f"grid cell .* cannot run: .*{match}"):
        run_sweep(spec, tmp_path, progress=False)
    assert not (tmp_path / "tasks").exists()


def test_a_record_of_the_wrong_shape_is_set_aside_not_fatal(tmp_path):
    spec = parse_spec('kind = "servo"\n[axes]\ntracker = ["ground_truth"]\n[fixed]\nsteps = 2\nscenario = "clear"\n'
                      'camera = "ideal"\n')
    run_sweep(spec, tmp_path, progress=False)
    task = next((tmp_path / "tasks").glob("*.json"))
    task.write_text(json.dumps({"status": "ok", "metrics": [1]}))
    counts = run_sweep(spec, tmp_path, progress=False, retry_failed=False)
    assert counts["corrupt_rerun"] == 1 and json.loads(task.read_text())["status"] == "ok"
