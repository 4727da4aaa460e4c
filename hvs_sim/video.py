"""Track a target through footage (a video file or a folder of images) and write what was tracked: track.csv, the
annotated MP4 and, when asked, a rerun recording and a ROS 2 bag.

The library side of `hvs-sim track` (the command, its options and its --help are hvs_sim/cli/track.py); the
frames are read by hvs_sim/framesource.py. Conventions (pixel centres, the ROI, the corners' order, the pose) and the
outputs' columns are the command's --help.
"""

from __future__ import annotations

import csv
import logging
import re
import statistics
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from hvs_sim.cliargs import DEFAULT_TRACKER
from hvs_sim.errors import ConfigError, InputError, OutputError
from hvs_sim.framesource import FrameSource, open_frames
from hvs_sim.outputs import (
    check_apart,
    check_output_file,
    check_replaceable,
    fresh_out_dir,
    open_output,
    settle,
    temporary_beside,
)
from hvs_sim.plugins import check_any_tracker, make_any_tracker
from hvs_sim.tracking import Track
from hvs_sim.tracking.frames import check_roi

log = logging.getLogger(__name__)

CSV_NAME, VIDEO_NAME = "track.csv", "annotated.mp4"
CSV_COLUMNS = ("frame", "cx", "cy", "tx", "ty", "theta", "scale", "mode", "occlusion", "score", "ms")
INIT_MODE = "init"
ALIGN_MODE = "align"  # the updates whose time the summary reports (predict and lost skip the alignment)
# footage often shows a target that moves on its own, where the servo loop's static prior would veto it (`--target`)
TRACK_TARGET_DEFAULT = "auto"
MODE_COLOURS = {INIT_MODE: (255, 255, 255), "align": (0, 220, 0), "predict": (255, 170, 0), "lost": (255, 0, 0)}  # RGB
SHIFT_BITS = 4  # sub-pixel bits for cv2 drawing, so the outline sits where the tracker put it
DRAW_LIMIT_PX = 1e5  # clip coordinates before drawing so a wild pose cannot overflow int32
MARKER_PX = 12
LABEL_ORIGIN, LABEL_SCALE = (8, 20), 0.5
# plots/mode uses viz/rerun_log.py's codes (init counts as aligned); not imported from there because that
# module loads the whole simulator (loop, renderer, MuJoCo), which tracking footage does not need
MODE_PLOT_CODE = {INIT_MODE: 0, "align": 0, "predict": 1, "lost": 2}


# ---------------------------------------------------------------- input: the ROI


def parse_roi(text: str) -> tuple[int, int, int, int]:
    """'x,y,w,h' → four ints; the bounds are checked against the first frame later (check_roi)."""
    parts = [part.strip() for part in str(text).split(",")]
    # ASCII digits only: int() would also read "١٢٣" or "1_00"
    roi = tuple(int(p) for p in parts) if all(re.fullmatch(r"[+-]?[0-9]+", p) for p in parts) else ()
    if len(roi) != 4:
        raise InputError(f"--roi must be 4 integers x,y,w,h separated by commas (e.g. 120,80,64,48), got {text!r}")
    return roi



# ---------------------------------------------------------------- output: folder, CSV, video, rerun


def prepare_rrd(rrd) -> Path | None:
    return check_output_file(rrd, "--rrd")


def csv_row(index: int, track: Track) -> list:
    tx, ty, theta, scale = track.pose
    return [index, f"{track.center[0]:.4f}", f"{track.center[1]:.4f}", f"{tx:.4f}", f"{ty:.4f}", f"{theta:.6f}",
            f"{scale:.6f}", track.mode, f"{track.occlusion:.4f}", f"{track.score:.4f}", f"{track.ms:.3f}"]


def annotate(frame: np.ndarray, index: int, track: Track) -> np.ndarray:
    """The frame as BGR with the tracked outline, centre and a 'frame mode' label, coloured by mode."""
    bgr = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
    colour = MODE_COLOURS.get(track.mode, MODE_COLOURS["lost"])[::-1]
    corners = np.clip(track.corners, -DRAW_LIMIT_PX, DRAW_LIMIT_PX)
    cv2.polylines(bgr, [np.round(corners * 2**SHIFT_BITS).astype(np.int32)], True, colour, 1, cv2.LINE_AA,
                  shift=SHIFT_BITS)
    centre = np.round(np.clip(track.center, -DRAW_LIMIT_PX, DRAW_LIMIT_PX)).astype(int)
    cv2.drawMarker(bgr, (int(centre[0]), int(centre[1])), colour, cv2.MARKER_CROSS, MARKER_PX, 1)
    for ink, thickness in (((0, 0, 0), 3), (colour, 1)):  # a dark outline keeps the label readable on any texture
        cv2.putText(bgr, f"{index} {track.mode}", LABEL_ORIGIN, cv2.FONT_HERSHEY_SIMPLEX, LABEL_SCALE, ink, thickness,
                    cv2.LINE_AA)
    return bgr


class RerunTrackLog:
    """Per-frame rerun logging: image, outline, centre and plots. Like viz/rerun_log.py it never raises
    into the tracking loop: the first failure is logged and logging stops."""

    def __init__(self, rrd: Path, fps: float, final: Path):
        import rerun as rr

        from hvs_sim.viz.rr_stream import ScalarColumns, jpeg, new_recording, plot_flush_steps

        self.rr, self.jpeg, self.fps, self.failed = rr, jpeg, fps, False
        self.final, self.error = final, None
        self.rec = new_recording("hvs_sim_track", rrd=str(rrd), blueprint=self._blueprint(), shown=final)
        self.plots = ScalarColumns(self.rec, "frame", "video_time", plot_flush_steps(live=False))
        self._guard(self._static)

    def _blueprint(self):
        import rerun.blueprint as rrb

        return rrb.Blueprint(rrb.Horizontal(
            rrb.Spatial2DView(name="frame", origin="video/image"),
            rrb.Vertical(rrb.TimeSeriesView(name="occlusion and score", origin="plots",
                                            contents=["plots/occlusion", "plots/score"]),
                         rrb.TimeSeriesView(name="update time", origin="plots", contents=["plots/ms"]),
                         rrb.TimeSeriesView(name="mode", origin="plots", contents=["plots/mode"])),
            column_shares=[3, 2]), collapse_panels=True)

    def _static(self) -> None:
        rr, rec = self.rr, self.rec
        rec.log("plots/occlusion", rr.SeriesLines(names="occlusion", colors=[120, 120, 120]), static=True)
        rec.log("plots/score", rr.SeriesLines(names="global match score", colors=[50, 120, 220]), static=True)
        rec.log("plots/ms", rr.SeriesLines(names="update time (ms)", colors=[220, 120, 50]), static=True)
        rec.log("plots/mode", rr.SeriesPoints(names="mode (0 align or init, 1 predict, 2 lost)"), static=True)

    def _guard(self, fn, *args) -> None:
        if self.failed:
            return
        try:
            fn(*args)
        except Exception as exc:  # noqa: BLE001 - logging must never stop the tracking
            self.failed = True
            log.warning("rerun logging disabled after error: %s", exc)

    def log(self, index: int, frame: np.ndarray, track: Track) -> None:
        self._guard(self._log, index, frame, track)

    def _log(self, index: int, frame: np.ndarray, track: Track) -> None:
        rr, rec, plot = self.rr, self.rec, self.plots
        colour = list(MODE_COLOURS.get(track.mode, MODE_COLOURS["lost"]))
        rec.set_time("frame", sequence=index)
        rec.set_time("video_time", duration=index / self.fps)
        rec.log("video/image", self.jpeg(frame))
        rec.log("video/image/tracked", rr.LineStrips2D([np.vstack([track.corners, track.corners[:1]])], colors=[colour]))
        rec.log("video/image/center", rr.Points2D([track.center], colors=[colour], radii=2.0))
        plot.at(index, index / self.fps)
        plot.add("plots/occlusion", track.occlusion)
        plot.add("plots/score", track.score)
        plot.add("plots/ms", track.ms)
        plot.add("plots/mode", MODE_PLOT_CODE.get(track.mode, MODE_PLOT_CODE["lost"]))

    def close(self) -> None:
        """Send the buffered plots and finish the file; `error` says why it is incomplete (then it is not kept)."""
        from hvs_sim.viz.rr_stream import finish_recording

        self._guard(self.plots.flush)
        try:
            finish_recording(self.rec, self.final)
        except OutputError as exc:
            self.error = exc


class TrackOutputs:
    """track.csv, annotated.mp4 and the optional .rrd and ROS 2 bag (`mcap`, a folder), written one frame at a time
    so memory stays flat, each under a temporary name beside its target and renamed into place when closed: a run
    that fails leaves no partial file and removes nothing it did not create; an earlier result stays until the new
    one is complete."""

    def __init__(self, out: Path, size: tuple[int, int], fps: float, rrd: Path | None = None,
                 mcap: Path | None = None):
        self.final = [p for p in (out / CSV_NAME, out / VIDEO_NAME, rrd, mcap) if p is not None]
        self.csv_path, self.video_path = temporary_beside(out / CSV_NAME), temporary_beside(out / VIDEO_NAME)
        self.rrd = None if rrd is None else temporary_beside(rrd)
        self.mcap = None if mcap is None else temporary_beside(mcap)
        self.bag = None
        self._open = ExitStack()  # closes whatever was opened, in reverse order
        try:
            self._start(size, fps)
        except BaseException:
            self.discard()
            raise

    def _start(self, size: tuple[int, int], fps: float) -> None:
        from hvs_sim.videoio import Mp4Writer

        self.video = Mp4Writer(self.video_path, fps, size, shown=self.final[1])  # H.264 (mp4v when PyAV's encoder is missing)
        self._open.callback(self.video.close)
        self.rerun = RerunTrackLog(self.rrd, fps, self.final[-1]) if self.rrd else None
        if self.rerun:
            self._open.callback(self.rerun.close)
        if self.mcap:
            from hvs_sim.viz.rosbag import FootageBag

            self.bag = FootageBag(self.mcap, fps, name=self.final[-1].name)
            self._open.callback(self.bag.close)
        self.csv = csv.writer(self._open.enter_context(open_output(self.csv_path)))
        self.csv.writerow(CSV_COLUMNS)

    def write(self, index: int, frame: np.ndarray, track: Track) -> None:
        self.csv.writerow(csv_row(index, track))
        self.video.write(cv2.cvtColor(annotate(frame, index, track), cv2.COLOR_BGR2RGB))
        if self.rerun:
            self.rerun.log(index, frame, track)
        if self.bag:
            self.bag.log(index, frame, track.corners, track.mode)

    def _temporaries(self) -> list[Path]:
        return [p for p in (self.csv_path, self.video_path, self.rrd, self.mcap) if p is not None]

    def close(self) -> None:
        """Close the files and rename each into place (the frames written so far, also after Ctrl-C)."""
        self._open.close()
        error = self.rerun.error if self.rerun else None  # an incomplete recording is removed, the rest kept
        for tmp, final in zip(self._temporaries(), self.final, strict=True):
            settle(tmp, final, keep=error is None or tmp != self.rrd)
        if error is not None:
            raise OutputError(f"{error}; the recording was removed, {self.final[0]} and {self.final[1]} are "
                              "complete") from error

    def discard(self) -> None:
        """Close and remove what this run wrote: a run that failed part-way leaves no result behind, and nothing that
        was there before it is touched."""
        try:
            self._open.close()
        finally:  # a close that fails again (a full disk) must not leave the temporaries behind
            for tmp, final in zip(self._temporaries(), self.final, strict=True):
                settle(tmp, final, keep=False)

    @property
    def paths(self) -> list[Path]:
        return list(self.final)


# ---------------------------------------------------------------- the run


@dataclass
class TrackResult:
    """What the run did, for the closing summary."""

    tracker: str
    outputs: list[Path]
    modes: Counter = field(default_factory=Counter)
    align_ms: list[float] = field(default_factory=list)  # aligned updates (init builds the template: not counted)
    other_ms: list[float] = field(default_factory=list)  # predicted and lost updates: cheap, and may be many
    interrupted: bool = False
    expected: int | None = None  # frames the source says it holds (a video's header), when it says
    notes: list[str] = field(default_factory=list)  # what the tracker said of this run (Tracker.notes)

    @property
    def frames(self) -> int:
        return sum(self.modes.values())

    def add(self, track: Track) -> None:
        self.modes[track.mode] += 1
        if track.mode == ALIGN_MODE:
            self.align_ms.append(track.ms)
        elif track.mode != INIT_MODE:
            self.other_ms.append(track.ms)

    def summary(self) -> str:
        modes = ", ".join(f"{m} {self.modes[m]}" for m in (INIT_MODE, "align", "predict", "lost"))
        aligned = f"{statistics.median(self.align_ms):.1f} ms" if self.align_ms else "n/a (no aligned frame)"
        other = (f"; predicted or lost updates apart: {statistics.median(self.other_ms):.1f} ms"
                 if self.other_ms else "")
        state = "interrupted after" if self.interrupted else "tracked"
        head = f"{state} {self.frames} frames with {self.tracker} ({modes}); median update on aligned frames {aligned}"
        lines = [head + other,
                 "outputs: " + ", ".join(map(str, self.outputs))]
        lines += [f"note: {n}" for n in self.notes]
        if self.expected is not None and self.frames < self.expected and not self.interrupted:
            lines.append(f"note: the video's header says {self.expected} frames; only {self.frames} could be decoded "
                         "(a truncated or damaged file)")
        return "\n".join(lines)


def target_settings(tracker: str, target: str | None, settings: dict) -> dict:
    """The tracker's settings with the target's motion (`--target`): the hybrid trackers take it (default `auto`:
    footage often shows a target that moves on its own); any other tracker has no motion prior to set."""
    from hvs_sim.tracking.hybrid import TARGET_MOTIONS
    from hvs_sim.tracking.registry import TRACKERS

    if target is not None and target not in TARGET_MOTIONS:
        raise ConfigError(f"--target must be one of {', '.join(TARGET_MOTIONS)}, got {target!r}")
    spec = TRACKERS.get(tracker)
    if spec is None or spec.base != "hybrid":
        if target is not None:
            raise ConfigError(f"--target sets the hybrid trackers' motion prior; {tracker} has none (it follows any "
                              "motion); leave --target out")
        return settings
    if target is not None and "target_motion" in settings and settings["target_motion"] != target:
        raise ConfigError(f"--target {target} and --set target_motion={settings['target_motion']} disagree; give one")
    chosen = target or settings.get("target_motion") or spec.config.get("target_motion") or TRACK_TARGET_DEFAULT
    return {**settings, "target_motion": chosen}


def track_footage(path, roi, tracker: str = DEFAULT_TRACKER, out="out/track", rrd=None,
                  progress: bool = True, settings: dict | None = None, overwrite: bool = False,
                  target: str | None = None, mcap=None, start: int = 0, end: int | None = None) -> TrackResult:
    """Check every input, then stream the frames through the tracker into the outputs.
    settings: the tracker's config fields (make_tracker keywords), e.g. other weights. An --out holding anything
    is refused unless `overwrite` (then its earlier track.csv and annotated.mp4 are replaced when this run ends).
    target: static | moving | auto, the hybrid's motion prior (target_settings; None: auto for the hybrids).
    mcap: a new folder for a ROS 2 bag of the frames, the tracked corners and the mode.
    start, end: track the clip's frames start..end-1 (the ROI is in frame `start`)."""
    tracker = check_any_tracker(tracker)
    settings = target_settings(tracker, target, dict(settings or {}))
    roi = parse_roi(roi) if isinstance(roi, str) else roi
    if mcap is not None and Path(mcap).exists():
        raise ConfigError(f"--mcap {mcap} exists: a ROS 2 bag is a new folder; give a path that does not exist")
    check_apart([path], {"--out's track.csv": Path(out) / CSV_NAME, "--out's annotated.mp4": Path(out) / VIDEO_NAME,
                         "--rrd": None if rrd is None else Path(rrd), "--mcap": None if mcap is None else Path(mcap)})
    check_replaceable({"--out's track.csv": Path(out) / CSV_NAME, "--out's annotated.mp4": Path(out) / VIDEO_NAME},
                      overwrite=True, root=out)  # never written through a link
    source = open_frames(path, start, end)
    try:
        roi = check_roi(roi, source.first.shape[:2])
        out = fresh_out_dir(out, overwrite, (CSV_NAME, VIDEO_NAME), clear=False, inputs=[path])
        rrd = prepare_rrd(rrd)
        method = make_any_tracker(tracker, **settings)
        outputs = TrackOutputs(out, source.size, source.fps, rrd, None if mcap is None else Path(mcap))
        result = TrackResult(tracker, outputs.paths, expected=source.count)
        bar = tqdm(total=source.count, unit="frame", desc=f"track/{tracker}", disable=not progress)
        try:
            result.interrupted = _run(method, roi, source, outputs, result, bar)
        finally:
            bar.close()
        result.notes = list(getattr(method, "notes", []) or [])
        return result
    finally:
        source.close()


def _run(method, roi, source: FrameSource, outputs: TrackOutputs, result: TrackResult, bar: tqdm) -> bool:
    """Track every frame; True when Ctrl-C stopped it (outputs kept), outputs removed on any error."""
    try:
        for index, (frame, track) in enumerate(_tracks(method, roi, source)):
            outputs.write(source.start + index, frame, track)
            result.add(track)
            bar.update(1)
    except KeyboardInterrupt:
        outputs.close()
        return True
    except BaseException:
        outputs.discard()
        raise
    outputs.close()
    return False


def _tracks(method, roi, source: FrameSource) -> Iterator[tuple[np.ndarray, Track]]:
    """(frame, track) for every frame; the first is the init frame, reported with mode "init"."""
    from hvs_sim.errors import HvsError, StateError

    t0 = time.perf_counter()
    try:
        first = method.init(source.first, roi)
        if first is None:  # an outside tracker's init may answer nothing: its template is the ROI
            first = _roi_track(roi)
        yield source.first, replace(first, mode=INIT_MODE, ms=1e3 * (time.perf_counter() - t0))
        for frame in source.rest:
            yield frame, method.update(frame)
    except HvsError:
        raise
    except Exception as exc:  # an outside tracker's own failure: say which and where, not a traceback
        raise StateError(f"tracker {getattr(method, 'name', '?')!r} failed: {type(exc).__name__}: {exc}") from exc


def _roi_track(roi) -> Track:
    """The ROI itself as a Track (identity pose): the first row for a tracker whose init reports nothing."""
    from hvs_sim.tracking.frames import roi_center, roi_corners

    return Track(center=roi_center(roi), corners=roi_corners(roi), pose=np.array([0.0, 0.0, 0.0, 1.0]),
                 mode=INIT_MODE, occlusion=0.0, score=1.0)
