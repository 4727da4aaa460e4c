"""Benchmarks at their --smoke size, through the CLI, and the demo entry point's outputs."""

import dataclasses
import json

import numpy as np
import pytest

from hvs_sim.cli import main
from hvs_sim.errors import ConfigError


def test_bench_track_smoke_writes_summary_csv_figures_and_table(tmp_path):
    out = tmp_path / "track"
    assert main(["bench", "track", "--smoke", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["provenance"]["command"].startswith("hvs-sim bench track")
    occ = summary["occlusion_scenarios"]
    from hvs_sim.bench.track import METHODS

    methods = set(METHODS)
    assert {"sift", "ecc", "deep_lk", "hybrid", "hybrid_paper"} <= methods
    assert set(occ) == methods
    for m, v in occ.items():
        for key in ("pct_le_1px", "pct_le_2px", "median_px", "p95_px", "max_px", "median_ms", "p95_ms", "pct_lost"):
            assert key in v["all"], (m, key)
    assert (out / "fig7_walk_by.png").stat().st_size > 10_000
    assert (out / "frames.csv").read_text().count("\n") == 1 + len(methods) * 40
    assert "| hybrid |" in (out / "table.md").read_text()


def test_bench_servo_smoke_writes_summary_figure_and_table(tmp_path):
    out = tmp_path / "servo"
    assert main(["bench", "servo", "--smoke", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    r = summary["results"]["walk_by"]
    assert set(r) == {"ground_truth", "hybrid"}
    for key in ("success_rate", "median_final_error_px", "mean_lost_steps"):
        assert key in r["hybrid"]
    assert len(summary["episodes"]) == 2 and "start_offset" in summary["episodes"][0]
    assert (out / "servo_walk_by.png").stat().st_size > 10_000
    assert "| ground_truth |" in (out / "table.md").read_text()


def test_cli_reports_bad_input_as_an_error_not_a_traceback(capsys):
    assert main(["run", "--scenario", "nope", "--steps", "2"]) == 2
    assert "accepted" in capsys.readouterr().err
    assert main(["run", "--scenario", "clear", "--tracker", "kcf", "--steps", "2"]) == 2
    assert "unknown tracker 'kcf'; accepted: ground_truth, none, hybrid" in capsys.readouterr().err
    assert main(["run", "--scenario", "clear", "--steps", "0"]) == 2
    assert main(["bench", "track", "--smoke", "--workers", "0"]) == 2


@pytest.mark.slow
def test_scene_command_writes_frames_and_ground_truth(tmp_path):
    out = tmp_path / "scene"
    assert main(["scene", "--scenario", "pause", "--frames", "5", "--format", "png", "--out", str(out)]) == 0
    assert len(list((out / "frames").glob("*.png"))) == 5
    assert (out / "ground_truth.csv").read_text().count("\n") == 6
    assert (out / "preview.png").exists() and (out / "ground_truth.npz").exists()


def test_servo_results_count_the_episodes_that_switched_to_the_near_goal_template():
    """A run with --near-goal-inset reports how many episodes switched (one that never did is the default template's
    figure under the near-goal's name); a run without it reports none. On the committed benchmark episodes."""
    from pathlib import Path

    from hvs_sim.bench.servo import method_results

    root = Path(__file__).resolve().parents[1] / "experiments" / "results" / "servo_context"
    for folder, switched in (("near_goal", 20), ("small", None)):
        eps = json.loads((root / folder / "summary.json").read_text())["episodes"]
        walk_by = [e for e in eps if e["scenario"] == "walk_by"]
        assert method_results(walk_by, 1.0)["near_goal_switched"] == switched
    never = [dict(e, near_goal=dict(e["near_goal"], switched_at_step=None)) for e in
             json.loads((root / "near_goal" / "summary.json").read_text())["episodes"][:3]]
    assert method_results(never, 1.0)["near_goal_switched"] == 0
    # the automatic template off for a method (ground truth: no template): no near-goal template to count
    off = [dict(e, near_goal={"inset_px": None, "auto": True, "off": "tracker 'ground_truth' has no template",
                              "switched_at_step": None}) for e in never]
    assert method_results(off, 1.0)["near_goal_switched"] is None
    assert method_results(off + never[:1], 1.0)["near_goal_switched"] == 0
    from hvs_sim.bench.servo import ServoBenchConfig
    from hvs_sim.errors import ConfigError

    with pytest.raises(ConfigError, match="no method here has one"):  # refused before any episode runs
        ServoBenchConfig(trackers=("ground_truth", "ecc:homography"), near_goal_scale=0.25)
    ServoBenchConfig(trackers=("ground_truth", "hybrid:homography"), near_goal_scale=0.25)


# what a record may differ in between two runs of one seed: how long things took
TIMING_KEYS = {"timing", "episode_seconds", "steps_per_second", "wall"}


def test_a_seeds_record_does_not_depend_on_the_worker_count(tmp_path):
    """One seed gives one episode record whether the benchmark runs on one worker or two (the torch thread count of
    an episode is fixed, bench/pool.EPISODE_THREADS): bit for bit, every field but the timings."""
    from hvs_sim.bench.servo import ServoBenchConfig, run_servo_bench

    records = {}
    for workers in (1, 2):
        cfg = ServoBenchConfig(trackers=("hybrid:homography",), scenarios=("pause",), seeds=(1000, 1001), steps=25,
                               width=320, height=240, workers=workers, camera="robot_cell")
        summary = run_servo_bench(cfg, tmp_path / str(workers), progress=False)
        records[workers] = [{k: v for k, v in e.items() if k not in TIMING_KEYS} for e in summary["episodes"]]
    assert [e["episode_seed"] for e in records[1]] == [1000, 1001]
    assert records[1] == records[2]


def test_records_read_back_bit_for_bit():
    """An episode's or sequence's record (bench/pool.to_record) gives back the same numbers, images and labels."""
    from hvs_sim.bench.pool import from_record, to_record

    value = ("k", {"error": np.array([0.1, 1 / 3, np.nan]), "mode": np.array(["track", "lost"]),
                   "img": np.arange(24, dtype=np.uint8).reshape(2, 4, 3), "n": np.int64(3), "t": (1, 2.5)})
    back = from_record(json.loads(json.dumps(to_record(value))))
    assert back[0] == "k" and back[1]["n"] == 3 and back[1]["t"] == [1, 2.5]
    np.testing.assert_array_equal(back[1]["error"], value[1]["error"])
    assert back[1]["mode"].tolist() == ["track", "lost"]
    assert back[1]["img"].dtype == np.uint8 and np.array_equal(back[1]["img"], value[1]["img"])


def _interrupt_after(n, fn):
    """A job function that runs n jobs, then raises KeyboardInterrupt as Ctrl-C would (deterministically)."""
    calls = []

    def job(args):
        if len(calls) == n:
            raise KeyboardInterrupt
        calls.append(args)
        return fn(args)
    return job, calls


def test_an_interrupted_servo_bench_keeps_its_episodes_and_resumes_to_the_same_records(tmp_path, monkeypatch):
    """Each episode is recorded as it ends; an interrupted run's summary holds them, marked partial; --resume runs only
    the missing episodes, and its records are those of a run never interrupted (timings apart)."""
    from hvs_sim.bench import servo
    from hvs_sim.bench.pool import RECORDS_DIR
    from hvs_sim.bench.servo import ServoBenchConfig, run_servo_bench

    cfg = ServoBenchConfig(trackers=("ground_truth",), scenarios=("pause",), seeds=(1000, 1001, 1002), steps=10,
                           width=320, height=240, camera="robot_cell")
    whole = run_servo_bench(cfg, tmp_path / "whole", progress=False)
    real = servo._episode
    job, calls = _interrupt_after(1, real)
    monkeypatch.setattr(servo, "_episode", job)
    with pytest.raises(KeyboardInterrupt):
        run_servo_bench(cfg, tmp_path / "cut", progress=False)
    partial = json.loads((tmp_path / "cut" / "summary.json").read_text())
    assert partial["interrupted"] and (partial["completed_jobs"], partial["total_jobs"]) == (1, 3)
    assert partial["records"][0]["key"] == ["pause", "ground_truth", 1000]
    assert len(list((tmp_path / "cut" / RECORDS_DIR).glob("pause*.json"))) == 1
    with pytest.raises(ConfigError, match="seeds"):  # other settings are refused, naming the field
        run_servo_bench(dataclasses.replace(cfg, seeds=(1000, 1001)), tmp_path / "cut", progress=False, resume=True)
    job, calls = _interrupt_after(99, real)
    monkeypatch.setattr(servo, "_episode", job)
    resumed = run_servo_bench(cfg, tmp_path / "cut", progress=False, resume=True)
    assert [c[2] for c in calls] == [1001, 1002]  # only the missing episodes ran

    def records(summary):
        return [{k: v for k, v in e.items() if k not in TIMING_KEYS} for e in summary["episodes"]]
    assert records(resumed) == records(whole)
    assert "interrupted" not in json.loads((tmp_path / "cut" / "summary.json").read_text())


def test_bench_resume_on_the_command_line(tmp_path, capsys):
    """--resume refuses a folder with no records, and says a finished run has nothing to do."""
    from hvs_sim.cli import main

    out = tmp_path / "b"
    argv = ["bench", "track", "--smoke", "--methods", "ecc", "--scenarios", "clear", "--out", str(out)]
    assert main([*argv, "--resume"]) == 2
    assert "holds no episodes/" in capsys.readouterr().err
    assert main(argv) == 0
    assert main([*argv, "--resume"]) == 0
    assert "nothing to resume" in capsys.readouterr().out
    assert main([*argv, "--resume", "--overwrite"]) == 2


@dataclasses.dataclass(frozen=True)
class _PoolConfig:
    """A stand-in benchmark config for collect_jobs (what it reads: workers, and the fields it records)."""

    workers: int = 1
    frames: int = 5


def _sequence_job(job):
    """A stand-in tracking job: per-frame arrays, labels and a preview image, as bench track and natural return."""
    scen, mount, seed = job
    return (scen, mount, seed), {"error": np.arange(seed, dtype=float) / 3, "mode": np.array(["align"] * seed)}, \
        np.full((2, 3, 3), seed, np.uint8)


def test_collect_jobs_records_interrupts_and_resumes_any_benchmark(tmp_path, capsys):
    """The pool's part, for any benchmark: records per job, a partial summary without images, a resume that runs only
    what is missing (whatever --workers), and a refusal that names the differing setting."""
    from hvs_sim.bench.pool import RECORDS_DIR, collect_jobs

    jobs = [("walk_by", "handheld", seed) for seed in (2, 3, 4, 5)]
    job, calls = _interrupt_after(3, _sequence_job)
    with pytest.raises(KeyboardInterrupt):
        collect_jobs(job, jobs, _PoolConfig(), tmp_path, "bench track", "sequence", progress=True)
    assert "3 of 4 sequence(s) are recorded" in capsys.readouterr().err
    partial = json.loads((tmp_path / "summary.json").read_text())
    assert (partial["completed_jobs"], partial["total_jobs"]) == (3, 4)
    assert partial["records"][0]["result"][1] == {"image_shape": [2, 3, 3], "in": RECORDS_DIR}
    with pytest.raises(ConfigError, match="frames = 5, this command gives 6"):
        collect_jobs(_sequence_job, jobs, _PoolConfig(frames=6), tmp_path, "bench track", "sequence", False, True)
    job, calls = _interrupt_after(99, _sequence_job)
    done = collect_jobs(job, jobs, _PoolConfig(), tmp_path, "bench track", "sequence", False, resume=True)
    assert calls == [("walk_by", "handheld", 5)]
    whole = [_sequence_job(j) for j in jobs]
    for got, want in zip(done, whole, strict=True):
        assert got[0] == want[0] and np.array_equal(got[1]["error"], want[1]["error"])
        assert got[1]["mode"].tolist() == want[1]["mode"].tolist() and np.array_equal(got[2], want[2])
    again = collect_jobs(job, jobs, _PoolConfig(workers=2), tmp_path, "bench track", "sequence", False, resume=True)
    assert len(calls) == 1 and len(again) == 4  # all recorded: nothing runs, and --workers may differ


def test_a_new_run_in_a_used_folder_drops_the_earlier_records(tmp_path):
    """A run given a folder with an earlier run's records (bench --overwrite) removes them, so that a later --resume
    cannot mix them with its own; a file hvs_sim did not write there stays."""
    from hvs_sim.bench.pool import RECORDS_DIR, collect_jobs

    jobs = [("walk_by", "handheld", seed) for seed in (2, 3)]
    collect_jobs(_sequence_job, jobs, _PoolConfig(), tmp_path, "bench track", "sequence", False)
    (tmp_path / RECORDS_DIR / "mine.json").write_text("{}")
    collect_jobs(_sequence_job, jobs[:1], _PoolConfig(), tmp_path, "bench track", "sequence", False)
    names = sorted(p.name for p in (tmp_path / RECORDS_DIR).glob("*.json"))
    assert len(names) == 3 and "mine.json" in names and "run.json" in names
