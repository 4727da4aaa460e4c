"""Cheap per-step rerun logging, shared by the closed loop's logger and `hvs-sim track`'s recording.

Measured per 640×480 step here (rerun 0.41): `rr.Image(frame).compress(jpeg_quality=85)` takes
~2.6 ms against ~1.4 ms for OpenCV's libjpeg-turbo (`jpeg`), and every `rec.log(path, rr.Scalars(v))`
costs ~0.1 ms of Python, of which a servo step plots ~25. `ScalarColumns` buffers the plotted values
and sends each series as one column (`RecordingStream.send_columns`) every `flush_every` steps: a
live viewer's plots trail the images by at most that many steps; a saved .rrd holds the same data.

A recording that goes only to a file (`new_recording(spawn=False)`) is cut into far fewer, larger chunks:
rerun's file sink (0.28 on) keeps an index entry for every chunk it wrote until the file is closed (the
.rrd footer), so a long run's memory grows with its number of chunks. Measured here (rerun 0.41, the
loop's entities logged from synthetic 640×480 steps at 30 Hz, steps 300 to 2 625): rerun's default batcher
(0.2 s ticks) with plots sent every 15 steps grew 14 MB per 1 000 steps; FILE_FLUSH_TICK_S,
FILE_FLUSH_BYTES and FILE_PLOT_FLUSH_STEPS below 0.4 MB. The cost: a file being written trails the run
by up to FILE_FLUSH_TICK_S (plots by FILE_PLOT_FLUSH_STEPS steps) until it is closed, which also
happens on Ctrl-C. `save(write_footer=False)` would keep no index at all, but rerun then reads the file
as a legacy stream (`RrdReader.store()` refuses it, random access is slow). A live viewer keeps rerun's
low-latency defaults (and their memory growth), and so does a user's own RERUN_FLUSH_* setting.

Light on imports on purpose: no MuJoCo, torch or scene module is loaded here (see video.py).
"""

from __future__ import annotations

import os

import numpy as np
import rerun as rr

from hvs_sim.errors import OutputError, StateError
from hvs_sim.sensor import encode_jpeg
from hvs_sim.validate import check_number

PLOT_FLUSH_STEPS = 15  # plotted values are sent every this many steps (0.5 s at 30 Hz) to a live viewer ...
FILE_PLOT_FLUSH_STEPS = 300  # ... and every this many (10 s at 30 Hz) to a file only
FILE_FLUSH_TICK_S = 5.0  # a file-only recording's batcher sends what it holds every this many seconds ...
FILE_FLUSH_BYTES = 16 * 2**20  # ... or when it holds this many bytes (~9 s of 640×480 JPEG frames at 30 Hz)
JPEG_QUALITY = 85  # recorded frames
FINISH_TIMEOUT_S = 20.0  # the longest a recording's last flush may take; a full disk otherwise waits forever


def jpeg(frame: np.ndarray, quality: int = JPEG_QUALITY) -> rr.EncodedImage:
    """An RGB (H×W×3) uint8 frame as a JPEG image for rerun (sensor.encode_jpeg)."""
    return rr.EncodedImage(contents=encode_jpeg(frame, quality).tobytes(), media_type="image/jpeg")


def new_recording(application_id: str, rrd: str | None = None, spawn: bool = False,
                  blueprint=None, shown=None) -> rr.RecordingStream:
    """A RecordingStream to a live viewer (`spawn`) and/or a file; without a viewer, batched in large chunks
    (module docstring). With both, one stream feeds both sinks: `spawn` and `save` each replace the sinks.
    shown: the name an error gives the file (the final name of a temporary `rrd`)."""
    own = any(k.startswith("RERUN_FLUSH_") for k in os.environ)  # the user's batcher setting wins
    batcher = None if spawn or own else rr.ChunkBatcherConfig(flush_tick=FILE_FLUSH_TICK_S,
                                                               flush_num_bytes=FILE_FLUSH_BYTES)
    rec = rr.RecordingStream(application_id, batcher_config=batcher)
    try:
        if spawn:
            rec.spawn(connect=False)  # starts the viewer; the sinks follow
            rec.set_sinks(rr.GrpcSink(), *([rr.FileSink(rrd)] if rrd else []), default_blueprint=blueprint)
        elif rrd:
            rec.save(rrd, default_blueprint=blueprint)
    except RuntimeError as exc:  # the file's header could not be written
        _abandon(rec)
        raise OutputError(f"could not start the rerun recording {shown or rrd} ({exc}: a full disk, or a folder that is "
                          "not writable?)") from exc
    return rec


def finish_recording(rec: rr.RecordingStream, path=None) -> None:
    """Flush what the batcher holds and close the sinks, waiting at most FINISH_TIMEOUT_S: rerun's own flush waits
    without a bound when its file writer has died (a full disk). OutputError when the recording is incomplete."""
    try:
        rec.flush(timeout_sec=FINISH_TIMEOUT_S)
    except Exception as exc:  # rerun raises RuntimeError for a dead writer and for the time-out
        _abandon(rec)
        named = "" if path is None else f" {path}"
        raise OutputError(f"could not finish the rerun recording{named} ({exc}: a full disk, or a folder that is "
                          "gone?)") from exc
    rec.disconnect()


def _abandon(rec: rr.RecordingStream) -> None:
    """Keep a stream whose file sink died from ever being flushed again: disconnect(), the stream's finaliser (also
    at interpreter exit) and rerun's exit handler each flush it without a bound (rerun-sdk 0.41). Its reference count
    is raised once so that it is never finalised; what it still held is lost (the file is incomplete anyway)."""
    import ctypes

    ctypes.pythonapi.Py_IncRef(ctypes.py_object(rec))
    rr.unregister_shutdown()


def plot_flush_steps(live: bool) -> int:
    """How many steps ScalarColumns buffers: few for a live viewer, many for a file only (module docstring)."""
    return PLOT_FLUSH_STEPS if live else FILE_PLOT_FLUSH_STEPS


class RowColumns:
    """Rows of rerun archetypes buffered per entity path and sent as columns (`RecordingStream.send_columns`) on two
    timelines, a sequence (`step`, `frame`) and a duration in seconds (`sim_time`, `video_time`), every `flush_every`
    steps: one call per entity and flush instead of one `rec.log` (~0.1 ms of Python each) per entity and step.

    Call `at(index, seconds)` once per step, then `add(path, archetype, **fields)` for each entity that has a row at
    that step (a path may skip steps; every row of a path gives the same fields), and `flush()` when the recording
    ends (also on interruption). `per_row` > 1: each field holds that many instances per row (boxes of several people).
    """

    def __init__(self, rec: rr.RecordingStream, sequence: str, duration: str, flush_every: int = PLOT_FLUSH_STEPS):
        check_number("flush_every", flush_every, 1, integer=True)
        self.rec, self.sequence, self.duration, self.flush_every = rec, sequence, duration, flush_every
        self._now: tuple[int, float] | None = None
        self._steps = 0  # steps buffered since the last flush
        self._rows: dict[str, tuple[type, int, list[int], list[float], dict[str, list]]] = {}

    def at(self, index: int, seconds: float) -> None:
        """Start a step; sends what is buffered once `flush_every` steps have been."""
        if self._steps >= self.flush_every:
            self.flush()
        self._now = (int(index), float(seconds))
        self._steps += 1

    def add(self, path: str, archetype: type, per_row: int = 1, **fields) -> None:
        if self._now is None:
            raise StateError(f"{type(self).__name__}.add before at(): no step to put the row at")
        kind, n, idx, secs, columns = self._rows.setdefault(path, (archetype, per_row, [], [], {}))
        if kind is not archetype or n != per_row or (columns and set(columns) != set(fields)):
            raise StateError(f"rows of {path!r} must all be {kind.__name__} with the same fields")
        idx.append(self._now[0])
        secs.append(self._now[1])
        for name, value in fields.items():
            (columns.setdefault(name, []).extend if per_row > 1 else columns.setdefault(name, []).append)(value)

    def flush(self) -> None:
        rows, self._rows, self._steps = self._rows, {}, 0
        for path, (archetype, per_row, idx, secs, columns) in rows.items():
            cols = archetype.columns(**columns)
            if per_row > 1:
                cols = cols.partition([per_row] * len(idx))
            self.rec.send_columns(path, indexes=[rr.TimeColumn(self.sequence, sequence=idx),
                                                 rr.TimeColumn(self.duration, duration=secs)], columns=cols)


class ScalarColumns(RowColumns):
    """Scalar plots as `RowColumns`: `add(path, value)` per plotted value (NaN is not plotted)."""

    def add(self, path: str, value: float) -> None:  # type: ignore[override]
        value = float(value)
        if self._now is None:
            raise StateError("ScalarColumns.add before at(): no step to put the value at")
        if np.isfinite(value):
            super().add(path, rr.Scalars, scalars=value)
