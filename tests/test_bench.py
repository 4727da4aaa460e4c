"""Benchmarks at their --smoke size, through the CLI, and the demo entry point's outputs."""

import json

import pytest

from hvs_sim.cli import main


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
