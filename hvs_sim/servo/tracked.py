"""A tracker's corners as an observation: the tracker started on the target's box in the episode's first frame,
answering that box's corners frame by frame, with s* for them (where the box's corners are at the goal). The gym env's
"features" with a tracker; apart from the env so that the env adapts the task and holds no tracking of its own."""

from __future__ import annotations

import numpy as np

from hvs_sim.errors import StateError
from hvs_sim.servo.task import ServoTask
from hvs_sim.tracking.frames import roi_corners, roi_from_corners


class TrackedCorners:
    """A tracker's corners on the task's frames; a fault keeps its last good corners and says so (mode "fault")."""

    def __init__(self, name: str, task: ServoTask):
        """A tracker of the registry or an outside one (hvs_sim.plugins), initialised on the episode's first frame at
        the target's box; StateError when it cannot start (the episode then has no features to give)."""
        from hvs_sim.plugins import make_any_tracker

        self.name, self.tracker = name, make_any_tracker(name)
        self.flag0 = task.truth(occlusion=False).corners  # the target's corners in the first frame
        roi = roi_from_corners(self.flag0)
        self.roi0 = roi_corners(roi)  # the tracked box's corners in the first frame; s* is where they go at the goal
        world = task.world
        self.desired = world.renderer.transfer(self.flag0, world.desired, self.roi0)
        try:
            track = self.tracker.init(world.renderer.rgb(), roi)
        except Exception as exc:  # the episode cannot give features: say so, as the loop does
            raise StateError(f"tracker {name!r} could not start on the first frame: {type(exc).__name__}: {exc}") \
                from exc
        self.corners = self.roi0 if track is None else track.corners  # an outside tracker's init may answer nothing
        self.mode, self._fresh = "init", True
        self.fault: str | None = None  # the last update's fault (None: it tracked)

    def update(self, frame: np.ndarray) -> np.ndarray:
        """The corners in `frame` (the first call: those of the frame the tracker was initialised on)."""
        if self._fresh:
            self._fresh = False
            return np.asarray(self.corners, np.float64).copy()
        try:
            track = self.tracker.update(frame)
            if not np.all(np.isfinite(track.corners)):
                raise FloatingPointError("tracker returned non-finite corners")
            self.corners, self.mode, self.fault = track.corners, str(track.mode), None
        except Exception as exc:  # noqa: BLE001 - a tracker fault is reported, the episode goes on
            self.mode, self.fault = "fault", f"{type(exc).__name__}: {exc}"
        return np.asarray(self.corners, np.float64).copy()
