"""One closed-loop episode end to end: loop + optional rerun logging + JSON summary."""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from hvs_sim.errors import ConfigError, OutputError
from hvs_sim.outputs import open_output, output_error, settle, temporary_beside, write_atomic
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.records import RunStats, StepRecord

FIGURE_RISING_OCCLUSION = 0.3  # frames.png's second tile: the first step with more of the target hidden


def run_episode(scenario: Scenario, tracker: str, config: LoopConfig | None = None, rrd: str | None = None,
                spawn: bool = False, progress: bool = True, json_path: str | None = None,
                keep_records: bool = False, tracker_settings: dict | None = None,
                figures: str | Path | None = None, mcap: str | Path | None = None) -> tuple[dict, list[StepRecord]]:
    """Run and summarise one episode; write an .rrd, JSON (+ per-step CSV), a ROS 2 bag (`mcap`, a new folder) and
    figures when paths are given.

    Memory stays flat in the number of steps: the summary is accumulated (RunStats), the CSV rows and the
    recording are written as the run goes, and only the frames the figures show are held. The records are
    returned only with keep_records (then they hold everything but the frames).
    tracker_settings: the tracker's config fields (make_tracker keywords)."""
    from tqdm.auto import tqdm

    logger = rrd_tmp = csv_tmp = None
    config = LoopConfig() if config is None else config
    if figures and not config.keep_frames:
        raise ConfigError("figures need the frames: LoopConfig(keep_frames=True)")
    loop = ServoLoop(scenario, tracker, config, **(tracker_settings or {}))
    if rrd or spawn:
        from hvs_sim.viz.rerun_log import RerunLogger, recording
        from hvs_sim.viz.rr_stream import plot_flush_steps

        if rrd:
            Path(rrd).parent.mkdir(parents=True, exist_ok=True)
            rrd_tmp = temporary_beside(rrd)  # renamed into place once the recording is closed
        try:
            rec = recording("hvs_sim", rrd=rrd_tmp, spawn=spawn, shown=rrd)
        except OutputError:  # a full disk before the first step: nothing of this run is left
            if rrd_tmp is not None:
                settle(rrd_tmp, rrd, keep=False)
            raise
        setup = {"scenario": scenario.name, "mount": scenario.mount, "seed": scenario.seed, "tracker": tracker,
                 "camera": scenario.camera.sensor.name, "target": scenario.target_label, "wall": scenario.wall,
                 "people": scenario.people, "start_offset": list(scenario.start_offset), "loop": asdict(config)}
        logger = RerunLogger(rec, loop.renderer.K, scenario.camera.width, scenario.camera.height,
                             loop.scene.target_corners_world(), config=setup, wall=loop.scene.wall_box(),
                             arm_meshes=loop.scene.arm_meshes(), background=True,
                             plot_flush_every=plot_flush_steps(live=spawn), rrd=rrd)
    bag = bag_tmp = None
    if mcap:
        from hvs_sim.viz.rosbag import BagRecorder, target_frame

        Path(mcap).parent.mkdir(parents=True, exist_ok=True)
        bag_tmp = temporary_beside(Path(mcap))  # renamed into place once the bag is closed
        rig = getattr(loop.scene, "rig", None)
        bag = BagRecorder(bag_tmp, loop.renderer.K, scenario.camera.width, scenario.camera.height,
                          joint_names=[j.name for j in getattr(rig, "joints", [])] if scenario.mount == "arm" else (),
                          target=target_frame(loop.scene.target_corners_world()),
                          distortion=scenario.camera.sensor.distortion, name=Path(mcap).name)
    stats = RunStats(config, loop.near_goal_plan)
    picks = FramePicks(config.steps) if figures else None
    records: list[StepRecord] = []
    csv_file = steps_csv = None
    if json_path:
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        csv_tmp = temporary_beside(steps_csv_path(json_path))  # renamed into place when closed
        csv_file = open_output(csv_tmp)  # closed in finally
        steps_csv = csv.writer(csv_file)
        steps_csv.writerow(STEP_COLUMNS)
    bar = tqdm(total=config.steps, disable=not progress, desc=f"{scenario.name}/{tracker}", unit="step")
    interrupted = completed = False
    try:
        for r in loop:
            t0 = time.perf_counter()
            if logger is not None:
                logger.log_step(r)
            if bag is not None:
                bag.log_step(r)
            r.timings["log"] = 1e3 * (time.perf_counter() - t0)
            stats.add(r)
            if steps_csv is not None:
                steps_csv.writerow(step_row(r))
            if picks is not None:
                picks.offer(r)
            r.frame = None
            if keep_records:
                records.append(r)
            bar.update(1)
            occ = "" if np.isnan(r.occlusion) else f"{r.occlusion:.0%}"
            bar.set_postfix(err=f"{r.error_px:.2f}px", mode=r.mode, occ=occ, refresh=False)
        completed = True
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM turned into one by the CLI: keep what was done, then go on
        interrupted = True
        raise
    finally:
        bar.close()
        keep = completed or (interrupted and stats.n > 0)  # a run that failed leaves no half result behind
        if csv_file is not None:
            try:
                csv_file.close()
            except OSError as exc:  # its last rows did not fit on the disk: no truncated CSV is left
                settle(csv_tmp, steps_csv_path(json_path), keep=False)
                raise output_error(steps_csv_path(json_path), exc) from None
            settle(csv_tmp, steps_csv_path(json_path), keep)
        if logger is not None:  # a complete recording of the steps so far, whatever stopped the run
            logger.drain()  # the queued steps first: whether logging failed is known after them
            if stats.n:
                logger.log_summary(_summary(scenario, tracker, stats, logger, interrupted))
            logger.close()
            if rrd_tmp is not None and rrd_tmp.exists():  # a complete recording of the steps so far
                settle(rrd_tmp, rrd, keep and logger.error is None)  # an unfinished recording is removed
        if bag is not None:
            bag.close()
            settle(bag_tmp, Path(mcap), keep)
        if json_path and keep:  # with the settings the loop decided for those the config left to it
            saved = {**_summary(scenario, tracker, stats, logger, interrupted), "resolved": resolved_json(loop),
                     "tracker_contract": getattr(loop.tracker, "contract_note", None)}
            write_atomic(json_path, json.dumps(saved, indent=2))
    summary = _summary(scenario, tracker, stats, logger, False)
    # an outside tracker whose first answer looked like another corner convention (plugins.contract_note)
    summary["tracker_contract"] = getattr(loop.tracker, "contract_note", None)
    if figures:
        from hvs_sim.viz.figures import run_figures

        summary["figures"] = [str(p) for p in run_figures(picks.records(), stats.series(), summary, Path(figures),
                                                           config.converge_px)]
    return summary, records


class FramePicks:
    """The four steps `frames.png` shows, chosen as the run goes so that only their frames are held: the
    start, the first step over FIGURE_RISING_OCCLUSION, the peak occlusion, the end (without occlusion
    figures, evaluate=False: the thirds of the run)."""

    def __init__(self, steps: int):
        self.steps = steps
        self.start = self.rising = self.peak = self.last = None
        self.thirds: dict[int, StepRecord] = {}

    def offer(self, r: StepRecord) -> None:
        keep = dataclasses.replace(r, people=[], arm=None)
        if self.start is None:
            self.start = keep
        occ = r.occlusion
        if np.isfinite(occ):
            if self.rising is None and occ > FIGURE_RISING_OCCLUSION:
                self.rising = keep
            if self.peak is None or occ > self.peak.occlusion:
                self.peak = keep
        if r.step in (self.steps // 3, 2 * self.steps // 3):
            self.thirds[r.step] = keep
        self.last = keep

    def records(self) -> list[StepRecord]:
        if self.start is None:
            return []
        if self.peak is not None and self.peak.occlusion > 0:
            middle = [self.rising or self.start, self.peak]
        else:  # the thirds of the run; a run cut short of them shows its last step there
            middle = (([self.thirds[k] for k in sorted(self.thirds)] or [self.start]) + [self.last])[:2]
        return [self.start, *middle, self.last]


def resolved_json(loop: ServoLoop) -> dict:
    """ServoLoop.resolved as JSON values (tuples as lists)."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(loop.resolved).items()}


def _summary(scenario, tracker, stats: RunStats, logger, interrupted: bool) -> dict:
    out = {"scenario": scenario.name, "mount": scenario.mount, "arm": scenario.arm if scenario.mount == "arm" else None,
           "seed": scenario.seed, "tracker": tracker,
           "camera": scenario.camera.sensor.name, "target": scenario.target_label, "wall": scenario.wall,
           "people": scenario.people, "interrupted": interrupted}
    if stats.n:
        out.update(stats.summary())
        out["steps_run"] = stats.n
    out["logging_failed"] = bool(logger and logger.failed)
    if stats.n and logger is not None and logger.written:  # beside the loop: not in the step's stages
        out["timing"]["recording_thread"] = {
            "mean_ms": logger.writer_cpu_ms / logger.written,
            "note": "CPU time a step's recording took, in the writer thread (beside the loop, on the same cores: its "
                    "share of the step's wall time shows in the stages it slowed) and in the last rows sent at the end"}
    if logger is not None and logger.error is not None:
        out["recording_error"] = logger.error + "; the recording was removed"
    return out


STEP_COLUMNS = ("step", "time", "mode", "error_px", "tracker_error_px", "occlusion", "vx", "vy", "vz", "wx", "wy", "wz",
                "gain", "saturated", "fault", "pose_x_mm", "pose_y_mm", "pose_z_mm", "pose_about_x_deg", "pose_about_y_deg",
                "pose_about_z_deg", "condition_L")


def steps_csv_path(json_path) -> Path:
    """run.json → run_steps.csv: the per-step records beside the summary, readable without rerun."""
    p = Path(json_path)
    return p.with_name(p.stem + "_steps.csv")


def step_row(r: StepRecord) -> list:
    return [r.step, f"{r.time:.4f}", r.mode, f"{r.error_px:.4f}", f"{r.tracker_error_px:.4f}",
            "" if np.isnan(r.occlusion) else f"{r.occlusion:.4f}", *(f"{v:.6f}" for v in r.twist), f"{r.gain:.4f}",
            int(r.saturated), r.fault or "", *(f"{v:.4f}" for v in r.pose_error),
            "" if r.condition is None else f"{r.condition:.1f}"]
