"""A recording that goes only to a file is cut into few chunks (rr_stream.new_recording): rerun's file sink keeps
an index entry per chunk until the file is closed, so chunks per step is what a long run's memory grows with."""

import time

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from hvs_sim.errors import ConfigError
from hvs_sim.render.camera import CameraPose
from hvs_sim.servo.records import StepRecord
from hvs_sim.viz.rerun_log import RerunLogger, recording
from hvs_sim.viz.rr_stream import FILE_PLOT_FLUSH_STEPS, PLOT_FLUSH_STEPS, ScalarColumns, plot_flush_steps

K = np.array([[80.0, 0, 40], [0, 80, 30], [0, 0, 1]])
STEPS = 60
PACE_S = 0.01  # 0.6 s in all: three of rerun's default 0.2 s batcher ticks


def record(k: int) -> StepRecord:
    rng = np.random.default_rng(k)
    corners = np.array([[20.0, 15], [60, 15], [60, 45], [20, 45]]) + rng.normal(0, 0.5, (4, 2))
    return StepRecord(step=k, time=k / 30, frame=rng.integers(0, 255, (60, 80, 3), dtype=np.uint8), track=None,
                      mode="align", features=corners, gt_features=corners, desired=corners, error_px=1.0,
                      tracker_error_px=0.1, occlusion=0.0, twist=rng.normal(size=6), qdot=rng.normal(size=6),
                      q=np.zeros(6), camera=CameraPose(R=np.eye(3), t=rng.normal(size=3)), gain=1.0, saturated=False,
                      limit_blocked=(), fault=None, timings={}, singular_values=np.ones(6))


def chunks_per_entity(rrd) -> dict[str, int]:
    out: dict[str, int] = {}
    for chunk in RrdReader(str(rrd)).store().stream():
        if not chunk.is_static:
            out[chunk.entity_path] = out.get(chunk.entity_path, 0) + 1
    return out


def write(rrd, flush_every: int) -> dict[str, int]:
    logger = RerunLogger(recording("hvs_sim_test", rrd=str(rrd)), K, 80, 60, background=True,
                         plot_flush_every=flush_every)
    for k in range(STEPS):
        logger.log_step(record(k))
        time.sleep(PACE_S)
    logger.close()
    return chunks_per_entity(rrd)


def test_a_file_only_recording_holds_each_entity_in_few_chunks(tmp_path, monkeypatch):
    assert plot_flush_steps(live=False) == FILE_PLOT_FLUSH_STEPS > STEPS
    assert plot_flush_steps(live=True) == PLOT_FLUSH_STEPS < STEPS
    file_only = write(tmp_path / "file.rrd", plot_flush_steps(live=False))
    # every step's frame and pose, batched over 5 s ticks: one chunk (two if a tick fell inside the 0.6 s)
    assert file_only["/world/camera/image"] <= 2 and file_only["/world/camera"] <= 2
    assert file_only["/plots/error_px"] == 1 and file_only["/plots/twist/vx"] == 1  # sent once, at close
    # a user's own batcher setting wins (here rerun's default 0.2 s tick), and the live viewer's plot interval
    monkeypatch.setenv("RERUN_FLUSH_TICK_SECS", "0.2")
    live = write(tmp_path / "default.rrd", plot_flush_steps(live=True))
    assert live["/world/camera/image"] >= 3 and live["/plots/error_px"] == STEPS // PLOT_FLUSH_STEPS


def test_a_live_viewer_and_a_file_both_get_the_steps(tmp_path, monkeypatch):
    """`spawn` and `save` each replace a stream's sinks: with both, the stream tees to the viewer and the file."""
    spawned = []
    monkeypatch.setattr(rr.RecordingStream, "spawn", lambda self, **kw: spawned.append(kw))
    monkeypatch.setattr(rr, "GrpcSink", lambda: rr.FileSink(str(tmp_path / "viewer.rrd")))  # the viewer's sink
    rec = recording("hvs_sim_test", rrd=str(tmp_path / "run.rrd"), spawn=True)
    for k in range(5):
        rec.set_time("step", sequence=k)
        rec.log("world/camera", rr.Transform3D(translation=[k, 0.0, 0.0]))
    rec.flush()
    rec.disconnect()
    assert spawned == [{"connect": False}]
    for name in ("viewer.rrd", "run.rrd"):
        steps = [s for c in RrdReader(str(tmp_path / name)).store().stream() if c.entity_path == "/world/camera"
                 for s in c.to_record_batch().column("step").to_pylist()]
        assert sorted(steps) == list(range(5)), name


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "15"])
def test_the_plot_interval_is_checked(bad):
    with pytest.raises(ConfigError, match="flush_every"):
        ScalarColumns(rr.RecordingStream("hvs_sim_test"), "step", "sim_time", bad)


def test_every_step_of_every_entity_is_in_the_recording_sent_as_columns(tmp_path):
    """The logger buffers its entities' rows and sends them as columns (rr_stream.RowColumns): a file holds one row per
    step of the frame, the truth's and the tracker's outline, one per moved pose, and the plots', none lost at close."""
    rrd = tmp_path / "rows.rrd"
    logger = RerunLogger(recording("hvs_sim_test", rrd=str(rrd)), K, 80, 60, background=True,
                         plot_flush_every=plot_flush_steps(live=False))
    for k in range(STEPS):
        logger.log_step(record(k))
    logger.close()
    rows: dict[str, int] = {}
    for chunk in RrdReader(str(rrd)).store().stream():
        if not chunk.is_static:
            rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    for path in ("/world/camera/image", "/world/camera/image/ground_truth", "/world/camera/image/tracked",
                 "/world/camera/image/desired", "/world/camera", "/plots/error_px", "/plots/twist/vx"):
        assert rows[path] == STEPS, (path, rows.get(path))  # these records' camera and s* move at every step


def test_row_columns_refuse_rows_that_do_not_match_a_paths_earlier_ones():
    from hvs_sim.errors import StateError
    from hvs_sim.viz.rr_stream import RowColumns

    cols = RowColumns(rr.RecordingStream("hvs_sim_test"), "step", "sim_time", 10)
    with pytest.raises(StateError, match="before at"):
        cols.add("a", rr.Transform3D, translation=[0.0, 0, 0])
    cols.at(0, 0.0)
    cols.add("a", rr.Transform3D, translation=[0.0, 0, 0])
    with pytest.raises(StateError, match="same fields"):
        cols.add("a", rr.Transform3D, mat3x3=np.eye(3))
