"""One closed-loop episode end to end: the loop's records through a list of sinks (the rerun recording, the ROS 2
bag, the per-step CSV, the figures' frame picks), each with on_step and close, and the JSON summary."""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import asdict
from functools import partial
from pathlib import Path
from typing import Protocol

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
    recording are written as the run goes (the sinks), and only the frames the figures show are held. The records
    are returned only with keep_records (then they hold everything but the frames).
    tracker_settings: the tracker's config fields (make_tracker keywords)."""
    from tqdm.auto import tqdm

    config = LoopConfig() if config is None else config
    if figures and not config.keep_frames:
        raise ConfigError("figures need the frames: LoopConfig(keep_frames=True)")
    loop = ServoLoop(scenario, tracker, config, **(tracker_settings or {}))
    stats = RunStats(config, loop.near_goal_plan)
    summary_now = partial(_summary, scenario, tracker, stats)  # (logger, interrupted) -> the run's summary so far
    rerun = RerunSink(loop, tracker, rrd, spawn, summary_now) if rrd or spawn else None
    bag = BagSink(loop, Path(mcap)) if mcap else None
    picks = FramePicks(config.steps) if figures else None
    csv_sink = CsvSink(json_path) if json_path else None
    sinks: list[Sink] = [s for s in (csv_sink, rerun, bag, picks) if s is not None]  # closed in this order
    logger = rerun.logger if rerun is not None else None
    records: list[StepRecord] = []
    bar = tqdm(total=config.steps, disable=not progress, desc=f"{scenario.name}/{tracker}", unit="step")
    interrupted = completed = False
    try:
        for r in loop:
            t0 = time.perf_counter()
            for sink in sinks:
                if sink.timed:
                    sink.on_step(r)
            r.timings["log"] = 1e3 * (time.perf_counter() - t0)
            stats.add(r)
            for sink in sinks:
                if not sink.timed:
                    sink.on_step(r)
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
        for sink in sinks:
            sink.close(keep, interrupted)
        if json_path and keep:  # with the settings the loop decided for those the config left to it
            saved = {**summary_now(logger, interrupted), "resolved": resolved_json(loop),
                     "tracker_contract": getattr(loop.tracker, "contract_note", None)}
            write_atomic(json_path, json.dumps(saved, indent=2))
    summary = summary_now(logger, False)
    # an outside tracker whose first answer looked like another corner convention (plugins.contract_note)
    summary["tracker_contract"] = getattr(loop.tracker, "contract_note", None)
    if figures:
        from hvs_sim.viz.figures import run_figures

        summary["figures"] = [str(p) for p in run_figures(picks.records(), stats.series(), summary, Path(figures),
                                                           config.converge_px)]
    return summary, records


class Sink(Protocol):
    """Where an episode's records go as the run goes. `timed`: its on_step counts as the step's "log" stage (the
    recordings); close(keep, interrupted) once, whatever stopped the run (keep: the run's output stands)."""

    timed: bool

    def on_step(self, r: StepRecord) -> None: ...

    def close(self, keep: bool, interrupted: bool) -> None: ...


class RerunSink:
    """The rerun recording (an .rrd renamed into place once closed, and/or a spawned viewer), with the run's summary
    logged at the end."""

    timed = True

    def __init__(self, loop: ServoLoop, tracker: str, rrd: str | None, spawn: bool,
                 summary: Callable[[object, bool], dict]):
        from hvs_sim.viz.rerun_log import RerunLogger, recording
        from hvs_sim.viz.rr_stream import plot_flush_steps

        self.rrd, self.tmp, self.summary, self.steps = rrd, None, summary, 0
        scenario, config = loop.scenario, loop.config
        if rrd:
            Path(rrd).parent.mkdir(parents=True, exist_ok=True)
            self.tmp = temporary_beside(rrd)  # renamed into place once the recording is closed
        try:
            rec = recording("hvs_sim", rrd=self.tmp, spawn=spawn, shown=rrd)
        except OutputError:  # a full disk before the first step: nothing of this run is left
            if self.tmp is not None:
                settle(self.tmp, rrd, keep=False)
            raise
        setup = {"scenario": scenario.name, "mount": scenario.mount, "seed": scenario.seed, "tracker": tracker,
                 "camera": scenario.camera.sensor.name, "target": scenario.target_label, "wall": scenario.wall,
                 "people": scenario.people, "start_offset": list(scenario.start_offset), "loop": asdict(config)}
        self.logger = RerunLogger(rec, loop.renderer.K, scenario.camera.width, scenario.camera.height,
                                  loop.scene.target_corners_world(), config=setup, wall=loop.scene.wall_box(),
                                  arm_meshes=loop.scene.arm_meshes(), background=True,
                                  plot_flush_every=plot_flush_steps(live=spawn), rrd=rrd)

    def on_step(self, r: StepRecord) -> None:
        self.logger.log_step(r)
        self.steps += 1

    def close(self, keep: bool, interrupted: bool) -> None:
        """A complete recording of the steps so far, whatever stopped the run; an unfinished one is removed."""
        self.logger.drain()  # the queued steps first: whether logging failed is known after them
        if self.steps:
            self.logger.log_summary(self.summary(self.logger, interrupted))
        self.logger.close()
        if self.tmp is not None and self.tmp.exists():
            settle(self.tmp, self.rrd, keep and self.logger.error is None)


class BagSink:
    """The ROS 2 bag (a new folder, renamed into place once closed)."""

    timed = True

    def __init__(self, loop: ServoLoop, mcap: Path):
        from hvs_sim.viz.rosbag import BagRecorder, target_frame

        scenario = loop.scenario
        mcap.parent.mkdir(parents=True, exist_ok=True)
        self.mcap, self.tmp = mcap, temporary_beside(mcap)
        rig = getattr(loop.scene, "rig", None)
        self.bag = BagRecorder(self.tmp, loop.renderer.K, scenario.camera.width, scenario.camera.height,
                               joint_names=[j.name for j in getattr(rig, "joints", [])] if scenario.mount == "arm"
                               else (), target=target_frame(loop.scene.target_corners_world()),
                               distortion=scenario.camera.sensor.distortion, name=mcap.name)

    def on_step(self, r: StepRecord) -> None:
        self.bag.log_step(r)

    def close(self, keep: bool, interrupted: bool) -> None:
        self.bag.close()
        settle(self.tmp, self.mcap, keep)


class CsvSink:
    """The per-step CSV beside run.json (steps_csv_path), written row by row."""

    timed = False

    def __init__(self, json_path):
        self.path = steps_csv_path(json_path)
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        self.tmp = temporary_beside(self.path)  # renamed into place when closed
        self.file = open_output(self.tmp)  # closed in close()
        self.writer = csv.writer(self.file)
        self.writer.writerow(STEP_COLUMNS)

    def on_step(self, r: StepRecord) -> None:
        self.writer.writerow(step_row(r))

    def close(self, keep: bool, interrupted: bool) -> None:
        try:
            self.file.close()
        except OSError as exc:  # its last rows did not fit on the disk: no truncated CSV is left
            settle(self.tmp, self.path, keep=False)
            raise output_error(self.path, exc) from None
        settle(self.tmp, self.path, keep)


class FramePicks:
    """The four steps `frames.png` shows, chosen as the run goes so that only their frames are held: the
    start, the first step over FIGURE_RISING_OCCLUSION, the peak occlusion, the end (without occlusion
    figures, evaluate=False: the thirds of the run). A sink: on_step offers it each record."""

    timed = False

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

    on_step = offer

    def close(self, keep: bool, interrupted: bool) -> None:
        """Nothing to write: the figures are drawn from the picks after the run."""

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
