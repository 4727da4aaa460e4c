"""Cheap per-step rerun logging, shared by the closed loop's logger and `hvs-sim track`'s recording.

Measured per 640×480 step here (rerun 0.41): `rr.Image(frame).compress(jpeg_quality=85)` takes
~2.6 ms against ~1.4 ms for OpenCV's libjpeg-turbo (`jpeg`), and every `rec.log(path, rr.Scalars(v))`
costs ~0.1 ms of Python, of which a servo step plots ~25. `ScalarColumns` buffers the plotted values
and sends each series as one column (`RecordingStream.send_columns`) every `flush_every` steps: a
live viewer's plots trail the images by at most that many steps; a saved .rrd holds the same data.

Light on imports on purpose: no MuJoCo, torch or scene module is loaded here (see video.py).
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from hvs_sim.camera_model import encode_jpeg
from hvs_sim.errors import ConfigError, StateError

PLOT_FLUSH_STEPS = 15  # plotted values are sent every this many steps (0.5 s at 30 Hz)
JPEG_QUALITY = 85  # recorded frames


def jpeg(frame: np.ndarray, quality: int = JPEG_QUALITY) -> rr.EncodedImage:
    """An RGB (H×W×3) uint8 frame as a JPEG image for rerun (camera_model.encode_jpeg)."""
    return rr.EncodedImage(contents=encode_jpeg(frame, quality).tobytes(), media_type="image/jpeg")


class ScalarColumns:
    """Scalar plots buffered per entity path and sent as columns on two timelines: a sequence (`step`,
    `frame`) and a duration in seconds (`sim_time`, `video_time`).

    Call `at(index, seconds)` once per step, then `add(path, value)` for each plotted value (a path may
    skip steps: NaN is not plotted), and `flush()` when the recording ends (also on interruption).
    """

    def __init__(self, rec: rr.RecordingStream, sequence: str, duration: str, flush_every: int = PLOT_FLUSH_STEPS):
        if flush_every < 1:
            raise ConfigError(f"flush_every must be ≥ 1, got {flush_every}")
        self.rec, self.sequence, self.duration, self.flush_every = rec, sequence, duration, flush_every
        self._now: tuple[int, float] | None = None
        self._steps = 0  # steps buffered since the last flush
        self._series: dict[str, tuple[list[int], list[float], list[float]]] = {}

    def at(self, index: int, seconds: float) -> None:
        """Start a step; sends what is buffered once `flush_every` steps have been."""
        if self._steps >= self.flush_every:
            self.flush()
        self._now = (int(index), float(seconds))
        self._steps += 1

    def add(self, path: str, value: float) -> None:
        if self._now is None:
            raise StateError("ScalarColumns.add before at(): no step to put the value at")
        value = float(value)
        if not np.isfinite(value):
            return
        idx, secs, vals = self._series.setdefault(path, ([], [], []))
        idx.append(self._now[0])
        secs.append(self._now[1])
        vals.append(value)

    def flush(self) -> None:
        series, self._series, self._steps = self._series, {}, 0
        for path, (idx, secs, vals) in series.items():
            self.rec.send_columns(path, indexes=[rr.TimeColumn(self.sequence, sequence=idx),
                                                 rr.TimeColumn(self.duration, duration=secs)],
                                  columns=rr.Scalars.columns(scalars=vals))
