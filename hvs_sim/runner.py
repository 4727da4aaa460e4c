"""One closed-loop episode end to end: loop + optional rerun logging + JSON summary."""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path

from hvs_sim.loop import LoopConfig, ServoLoop, StepRecord, summarize_run
from hvs_sim.scene.scenarios import Scenario


def run_episode(scenario: Scenario, tracker: str, config: LoopConfig | None = None, rrd: str | None = None,
                spawn: bool = False, progress: bool = True, json_path: str | None = None,
                keep_records: bool = False, tracker_settings: dict | None = None) -> tuple[dict, list[StepRecord]]:
    """Run and summarise one episode; write an .rrd and/or JSON when paths are given.
    tracker_settings: the tracker's config fields (make_tracker keywords)."""
    from tqdm.auto import tqdm

    logger = None
    config = LoopConfig() if config is None else config
    loop = ServoLoop(scenario, tracker, config, **(tracker_settings or {}))
    if rrd or spawn:
        from hvs_sim.viz.rerun_log import RerunLogger, recording

        if rrd:
            Path(rrd).parent.mkdir(parents=True, exist_ok=True)
        rec = recording("hvs_sim", rrd=rrd, spawn=spawn)
        setup = {"scenario": scenario.name, "mount": scenario.mount, "seed": scenario.seed, "tracker": tracker,
                 "camera": scenario.camera.sensor.name, "target": scenario.target_label, "wall": scenario.wall,
                 "people": scenario.people, "start_offset": list(scenario.start_offset), "loop": asdict(config)}
        logger = RerunLogger(rec, loop.renderer.K, scenario.camera.width, scenario.camera.height,
                             loop.renderer.target_corners_world(), config=setup, wall=loop.scene.wall_box(),
                             arm_meshes=loop.scene.arm_meshes())
    records = []
    bar = tqdm(total=config.steps, disable=not progress, desc=f"{scenario.name}/{tracker}", unit="step")
    interrupted = completed = False
    try:
        for r in loop:
            t0 = time.perf_counter()
            if logger is not None:
                logger.log_step(r)
            r.timings["log"] = 1e3 * (time.perf_counter() - t0)
            if not keep_records:
                r.frame = None
            records.append(r)
            bar.update(1)
            bar.set_postfix(err=f"{r.error_px:.2f}px", mode=r.mode, occ=f"{r.occlusion:.0%}", refresh=False)
        completed = True
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM turned into one by the CLI: keep what was done, then go on
        interrupted = True
        raise
    finally:
        bar.close()
        if logger is not None:  # a complete recording of the steps so far, whatever stopped the run
            if records:
                logger.log_summary(_summary(scenario, tracker, config, records, logger, interrupted))
            logger.rec.flush()
            logger.rec.disconnect()
        if json_path and (completed or (interrupted and records)):
            _write_summary(json_path, scenario, tracker, config, records, logger, interrupted)
    return _summary(scenario, tracker, config, records, logger, False), records


def _summary(scenario, tracker, config, records, logger, interrupted: bool) -> dict:
    out = {"scenario": scenario.name, "mount": scenario.mount, "seed": scenario.seed, "tracker": tracker,
           "camera": scenario.camera.sensor.name, "target": scenario.target_label, "wall": scenario.wall,
           "people": scenario.people, "interrupted": interrupted}
    if records:
        out.update(summarize_run(records, config))
        out["steps_run"] = len(records)
    out["logging_failed"] = bool(logger and logger.failed)
    return out


def _write_summary(json_path, scenario, tracker, config, records, logger, interrupted: bool) -> None:
    Path(json_path).parent.mkdir(parents=True, exist_ok=True)
    Path(json_path).write_text(json.dumps(_summary(scenario, tracker, config, records, logger, interrupted), indent=2))
    write_steps_csv(records, steps_csv_path(json_path))


STEP_COLUMNS = ("step", "time", "mode", "error_px", "tracker_error_px", "occlusion", "vx", "vy", "vz", "wx", "wy", "wz",
                "gain", "saturated", "fault", "pose_x_mm", "pose_y_mm", "pose_z_mm", "pose_about_x_deg", "pose_about_y_deg",
                "pose_about_z_deg", "condition_L")


def steps_csv_path(json_path) -> Path:
    """run.json → run_steps.csv: the per-step records beside the summary, readable without rerun."""
    p = Path(json_path)
    return p.with_name(p.stem + "_steps.csv")


def write_steps_csv(records, path: Path) -> None:
    import csv

    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(STEP_COLUMNS)
        for r in records:
            w.writerow([r.step, f"{r.time:.4f}", r.mode, f"{r.error_px:.4f}", f"{r.tracker_error_px:.4f}",
                        f"{r.occlusion:.4f}", *(f"{v:.6f}" for v in r.twist), f"{r.gain:.4f}", int(r.saturated),
                        r.fault or "", *(f"{v:.4f}" for v in r.pose_error),
                        "" if r.condition is None else f"{r.condition:.1f}"])
