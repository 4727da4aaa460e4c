"""rerun logging of closed-loop records.

Entity paths:
  world/camera                      camera pose (Transform3D, OpenCV axes) + Pinhole
  world/camera/image                rendered frame
  world/camera/image/tracked        the corners the controller used (green: the tracker's, through the feature
                                    filter when it is on), .../ground_truth (white), .../desired (red)
  world/trajectory                  the camera centre's path
  world/target                      target outline in 3-D
  world/occluder                    the people in front of it (boxes around their bodies)
  world/wall, world/arm/mesh_*      the picture board (box) and the arm's meshes (posed when they moved)
  run/config, run/summary           the run's set-up and, at the end, its summary (JSON text)
  plots/error_px, plots/tracker_error_px, plots/log10_error_px, plots/occlusion, plots/mode,
  plots/pose_error_mm, plots/pose_error_deg (the camera's pose error, truth), plots/condition_L, plots/rank_L
  plots/twist/{vx,vy,vz,wx,wy,wz}, plots/joint_velocity/j{1..6}
Library code takes a RecordingStream; logging never raises into the loop.
2-D overlays are shifted by half a pixel: hvs_sim puts pixel centres at integers (OpenCV), rerun's
image space at +0.5.
"""

from __future__ import annotations

import copy
import logging
import queue
import threading
import time

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from hvs_sim.sensor import encode_jpeg
from hvs_sim.servo.records import MODES, StepRecord
from hvs_sim.viz.rr_stream import JPEG_QUALITY, PLOT_FLUSH_STEPS, RowColumns, ScalarColumns, new_recording

log = logging.getLogger(__name__)
RERUN_PIXEL_OFFSET = 0.5  # hvs_sim pixel (OpenCV, centres at integers) → rerun image space (centres at +0.5)
TWIST = ("vx", "vy", "vz", "wx", "wy", "wz")
PATH_STEP_M = 0.001  # the drawn camera path gains a point when the camera has moved this far ...
PATH_MAX_POINTS = 2000  # ... and is thinned to half when it has more points than this
# background=True: at most this many steps wait for the writer thread; a loop that outruns it waits (so memory
# stays bounded) and that wait is what the loop's "log" stage then measures
LOG_QUEUE_STEPS = 4
TRAJECTORY_RGB, TRACKED_RGB, TRUTH_RGB, DESIRED_RGB, OCCLUDER_RGB = (80, 140, 255), (0, 255, 0), (255, 255, 255), \
    (255, 60, 60), (200, 120, 80)
TRACKED_RADIUS = 1.5  # px: the tracked outline drawn over the truth's
MOVED_TOL = 1e-6  # m (positions) and rotation-matrix entries: an entity moved less than this is not logged again


def _quat_xyzw(R: np.ndarray) -> list[float]:
    from hvs_sim.geometry import mat_to_quat

    w, x, y, z = mat_to_quat(R)
    return [x, y, z, w]


def blueprint() -> rrb.Blueprint:
    """Camera and 3-D views on the left; on the right three plot panels, each pair of related plots
    sharing a panel as tabs, so each plot is tall enough for its legend (six lines for the twist)."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(rrb.Spatial2DView(name="camera", origin="world/camera/image"),
                         rrb.Tabs(rrb.Spatial3DView(name="world", origin="world"),
                                  rrb.TextDocumentView(name="run", origin="run"))),
            rrb.Vertical(
                rrb.Tabs(rrb.TimeSeriesView(name="log10 pixel error", origin="plots",
                                            contents=["plots/log10_error_px", "plots/log10_tracker_error_px"]),
                         rrb.TimeSeriesView(name="pixel error", origin="plots",
                                            contents=["plots/error_px", "plots/tracker_error_px"]),
                         rrb.TimeSeriesView(name="pose error", origin="plots",
                                            contents=["plots/pose_error_mm", "plots/pose_error_deg"]),
                         rrb.TimeSeriesView(name="cond(L)", origin="plots",
                                            contents=["plots/condition_L", "plots/rank_L"])),
                rrb.TimeSeriesView(name="occlusion and mode", origin="plots", contents=["plots/occlusion", "plots/mode"]),
                rrb.Tabs(rrb.TimeSeriesView(name="camera twist", origin="plots/twist"),
                         rrb.TimeSeriesView(name="joint velocities", origin="plots/joint_velocity")),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def recording(application_id: str = "hvs_sim", rrd: str | None = None, spawn: bool = False,
              shown=None) -> rr.RecordingStream:
    """The loop's recording with its blueprint (rr_stream.new_recording: a file-only one is batched in large chunks)."""
    return new_recording(application_id, rrd=rrd, spawn=spawn, blueprint=blueprint(), shown=shown)


class RerunLogger:
    """Logs StepRecords to a RecordingStream. Failures are logged once and then ignored.

    background=True: the steps are logged by a writer thread (archetypes built, the frame JPEG-encoded) while the
    loop renders and tracks the next frame; the loop only hands a shallow copy of the record over (and waits only
    when LOG_QUEUE_STEPS are queued). `drain()` waits for the queued steps; `close()` drains, then finishes the
    recording."""

    def __init__(self, rec: rr.RecordingStream, K: np.ndarray, width: int, height: int, target_world: np.ndarray | None = None,
                 config: dict | None = None, wall: tuple | None = None, arm_meshes: list | None = None,
                 background: bool = False, plot_flush_every: int = PLOT_FLUSH_STEPS, rrd=None):
        """plot_flush_every: steps between sends of the plotted values (rr_stream.plot_flush_steps);
        config: the run's set-up, logged as text at run/config; wall: (centre, R, half sizes) of the board;
        arm_meshes: (vertices, triangles, RGBA) per arm mesh (Scene.arm_meshes), posed at the steps where they moved;
        rrd: the file the recording goes to, named when it cannot be finished."""
        self.rec, self.rrd = rec, rrd
        self.failed = False
        self.error: str | None = None  # why the recording could not be finished (then it is removed)
        self.background = background
        self._queue: queue.Queue | None = None
        self._writer: threading.Thread | None = None  # started by the first log_step, stopped by drain()
        self.writer_cpu_ms, self.written = 0.0, 0  # the writer thread's CPU time over the steps it wrote
        self.path: list[np.ndarray] = []
        self._last: dict[str, np.ndarray] = {}  # what each still-or-moving entity was last logged with (_moved)
        self.plots = ScalarColumns(rec, "step", "sim_time", plot_flush_every)  # plots/*
        # the 3-D and image entities, as columns too: every step to a live viewer (the images must not trail), else
        # with the plots
        self.view = RowColumns(rec, "step", "sim_time", 1 if plot_flush_every == PLOT_FLUSH_STEPS else plot_flush_every)
        self._guard(self._static, K, width, height, target_world)
        if config is not None:
            self._guard(self._text, "run/config", "set-up", config)
        if wall is not None:
            self._guard(self._wall, *wall)
        if arm_meshes:
            self._guard(self._arm, arm_meshes)

    def _write(self) -> None:
        """The writer thread: logs queued records until it takes the None that drain() puts (its CPU time counted in
        `writer_cpu_ms`: it runs beside the loop, on the same cores)."""
        while (r := self._queue.get()) is not None:
            t0 = time.thread_time()
            self._guard(self._step, r)
            self.writer_cpu_ms += 1e3 * (time.thread_time() - t0)
            self.written += 1

    def _arm(self, meshes) -> None:
        for k, (verts, faces, rgba) in enumerate(meshes):
            colour = (np.clip(rgba[:3], 0, 1) * 255).astype(np.uint8)
            self.rec.log(f"world/arm/mesh_{k}", rr.Mesh3D(vertex_positions=verts, triangle_indices=faces,
                                                           albedo_factor=colour), static=True)

    def _text(self, path: str, title: str, data: dict) -> None:
        import json

        body = json.dumps(data, indent=2, default=str)
        self.rec.log(path, rr.TextDocument(f"# {title}\n\n```json\n{body}\n```", media_type=rr.MediaType.MARKDOWN),
                     static=True)

    def _wall(self, centre, R, half_sizes) -> None:
        self.rec.log("world/wall", rr.Boxes3D(centers=[centre], half_sizes=[half_sizes],
                                              quaternions=[rr.Quaternion(xyzw=_quat_xyzw(R))], colors=[225, 215, 190],
                                              fill_mode=rr.components.FillMode.Solid), static=True)

    def log_summary(self, summary: dict) -> None:
        """The run's summary, at run/summary (written at the end, or when the run was interrupted)."""
        self._guard(self._text, "run/summary", "summary", summary)

    def drain(self) -> None:
        """Wait until the writer thread has logged every queued step, and stop it (`failed` is final then)."""
        if self._writer is not None:
            self._queue.put(None)
            self._writer.join()
            self._writer = self._queue = None

    def close(self) -> None:
        """Log what the writer has queued, send the buffered plots and finish the recording (also after an
        interruption)."""
        from hvs_sim.errors import OutputError
        from hvs_sim.viz.rr_stream import finish_recording

        self.drain()
        t0 = time.thread_time()
        self._guard(self.view.flush)
        self._guard(self.plots.flush)
        self.writer_cpu_ms += 1e3 * (time.thread_time() - t0)  # the rows still buffered: the recording's cost too
        try:
            finish_recording(self.rec, self.rrd)
        except OutputError as exc:  # the run goes on to write its JSON, which says so
            self.failed, self.error = True, str(exc)
            log.warning("%s", exc)

    def _guard(self, fn, *args) -> None:
        if self.failed:
            return
        try:
            fn(*args)
        except Exception as exc:  # noqa: BLE001 - logging must never stop the loop
            self.failed = True
            log.warning("rerun logging disabled after error: %s", exc)

    def _static(self, K, width, height, target_world) -> None:
        rec = self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log("world/camera", rr.Pinhole(image_from_camera=K, resolution=[width, height],
                                           camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=0.15), static=True)
        if target_world is not None:
            rec.log("world/target", rr.LineStrips3D([np.vstack([target_world, target_world[:1]])], colors=[255, 200, 0]), static=True)
        for name in TWIST:
            rec.log(f"plots/twist/{name}", rr.SeriesLines(names=name), static=True)
        rec.log("plots/error_px", rr.SeriesLines(names="ground-truth error to s* (px)", colors=[220, 50, 50]), static=True)
        rec.log("plots/tracker_error_px", rr.SeriesLines(names="tracker corner error (px)", colors=[50, 160, 50]), static=True)
        rec.log("plots/occlusion", rr.SeriesLines(names="true occlusion", colors=[120, 120, 120]), static=True)
        rec.log("plots/mode", rr.SeriesPoints(names=f"mode ({', '.join(f'{i} {m}' for i, m in enumerate(MODES))})"), static=True)
        rec.log("plots/log10_error_px", rr.SeriesLines(names="log10 ground-truth error (px)", colors=[220, 50, 50]),
                static=True)
        rec.log("plots/log10_tracker_error_px", rr.SeriesLines(names="log10 tracker error (px)", colors=[50, 160, 50]),
                static=True)
        rec.log("plots/pose_error_mm", rr.SeriesLines(names="camera pose error (mm, truth)", colors=[30, 90, 200]),
                static=True)
        rec.log("plots/pose_error_deg", rr.SeriesLines(names="camera pose error (deg, truth)", colors=[200, 120, 30]),
                static=True)
        rec.log("plots/condition_L", rr.SeriesLines(names="condition number of L"), static=True)
        rec.log("plots/rank_L", rr.SeriesLines(names="rank of L"), static=True)

    def _extend_path(self, t: np.ndarray) -> bool:
        """Add the camera centre to the drawn path when it has moved PATH_STEP_M; at PATH_MAX_POINTS
        every other point is dropped, so a long run's path costs bounded memory and logging time.
        Whether the path changed (and is logged again)."""
        if self.path and np.linalg.norm(t - self.path[-1]) < PATH_STEP_M:
            return False
        self.path.append(np.array(t, float))
        if len(self.path) > PATH_MAX_POINTS:
            self.path = self.path[:-1:2] + self.path[-1:]
        return True

    def _moved(self, entity: str, *values) -> bool:
        """Whether `entity` differs (by more than MOVED_TOL) from what it was last logged with; if so, remember
        it. A still arm, camera or person, and the constant s*, are logged once, not every step: a viewer shows
        an entity's latest value, and a converged run stands still for most of its steps."""
        v = np.concatenate([np.ravel(np.asarray(x, float)) for x in values]) if values else np.zeros(0)
        last = self._last.get(entity)
        if last is not None and last.shape == v.shape and np.all(np.abs(last - v) <= MOVED_TOL):
            return False
        self._last[entity] = v
        return True

    def log_step(self, r: StepRecord) -> None:
        if not self.background:
            self._guard(self._step, r)
            return
        if self.failed:
            return
        if self._writer is None:
            self._queue = queue.Queue(maxsize=LOG_QUEUE_STEPS)
            self._writer = threading.Thread(target=self._write, name="hvs_sim-rerun-writer", daemon=True)
            self._writer.start()
        self._queue.put(copy.copy(r))  # a copy: the caller may drop the record's frame once this returns

    def _step(self, r: StepRecord) -> None:
        view = self.view
        view.at(r.step, r.time)
        if self._moved("world/camera", r.camera.t, r.camera.R):
            view.add("world/camera", rr.Transform3D, translation=r.camera.t, mat3x3=r.camera.R)
        if self._extend_path(r.camera.t):
            view.add("world/trajectory", rr.LineStrips3D, strips=np.array(self.path), colors=TRAJECTORY_RGB)
        if r.frame is not None:
            view.add("world/camera/image", rr.EncodedImage, blob=encode_jpeg(r.frame, JPEG_QUALITY).tobytes(),
                     media_type="image/jpeg")
        closed = lambda p: np.vstack([p, p[:1]]) + RERUN_PIXEL_OFFSET
        if np.all(np.isfinite(r.features)):
            view.add("world/camera/image/tracked", rr.LineStrips2D, strips=closed(r.features), colors=TRACKED_RGB,
                     radii=TRACKED_RADIUS)
        view.add("world/camera/image/ground_truth", rr.LineStrips2D, strips=closed(r.gt_features), colors=TRUTH_RGB)
        if self._moved("world/camera/image/desired", r.desired):
            view.add("world/camera/image/desired", rr.LineStrips2D, strips=closed(r.desired), colors=DESIRED_RGB)
        if r.arm is not None:
            for k, (pos, R) in enumerate(zip(*r.arm)):
                if self._moved(f"world/arm/mesh_{k}", pos, R):
                    view.add(f"world/arm/mesh_{k}", rr.Transform3D, translation=pos, mat3x3=R)
        if r.people and self._moved("world/occluder", *(x for pose in r.people for x in pose)):
            view.add("world/occluder", rr.Boxes3D, per_row=len(r.people),
                     centers=[p + R @ np.array([0.0, 0.0, 0.9]) for p, R in r.people],
                     half_sizes=[[0.15, 0.3, 0.9]] * len(r.people),
                     quaternions=[rr.Quaternion(xyzw=_quat_xyzw(R)) for _, R in r.people],
                     colors=[OCCLUDER_RGB] * len(r.people))
        if view.flush_every == 1:  # a live viewer: this step's rows now, not at the next step's at()
            view.flush()
        plot = self.plots
        plot.at(r.step, r.time)
        plot.add("plots/error_px", r.error_px)
        plot.add("plots/log10_error_px", np.log10(max(r.error_px, 1e-3)))
        if np.isfinite(r.tracker_error_px):
            plot.add("plots/tracker_error_px", r.tracker_error_px)
            plot.add("plots/log10_tracker_error_px", np.log10(max(r.tracker_error_px, 1e-3)))
        plot.add("plots/pose_error_mm", np.linalg.norm(r.pose_error[:3]))
        plot.add("plots/pose_error_deg", np.linalg.norm(r.pose_error[3:]))
        if r.condition is not None:
            plot.add("plots/condition_L", r.condition)
            plot.add("plots/rank_L", r.rank)
        plot.add("plots/occlusion", r.occlusion)  # NaN (LoopConfig.evaluate=False) is not plotted
        plot.add("plots/mode", MODES.index(r.mode) if r.mode in MODES else MODES.index("fault"))
        for name, v in zip(TWIST, r.twist):
            plot.add(f"plots/twist/{name}", v)
        for i, v in enumerate(r.qdot):
            plot.add(f"plots/joint_velocity/j{i + 1}", v)
