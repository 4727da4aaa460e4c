"""The closed loop: render → track → control → step physics, one record per step.

Logging and plots only read the records. A tracker exception or non-finite output stops the arm
for that step (zero twist) and is written into the record; the loop goes on.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from hvs_sim.camera_model import undistort_points
from hvs_sim.control.arm import ArmLimits, camera_twist_to_world, twist_to_joint_velocities
from hvs_sim.control.ibvs import IBVSConfig, IBVSController
from hvs_sim.errors import ConfigError, StateError, choice_error
from hvs_sim.render.camera import CameraPose
from hvs_sim.render.renderer import GroundTruth, Renderer
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.scene.world import Scene
from hvs_sim.tracking import TRACKER_NAMES, Track, Tracker, make_tracker
from hvs_sim.tracking.frames import roi_corners, roi_from_corners

LOOP_TRACKERS = ("ground_truth",) + TRACKER_NAMES
MAX_STEPS = 100_000


@dataclass(frozen=True)
class LoopConfig:
    steps: int = 300
    converge_px: float = 0.5  # mean corner error to s* that counts as converged ...
    hold_steps: int = 10  # ... when held this many consecutive steps
    ibvs: IBVSConfig = field(default_factory=IBVSConfig)
    keep_frames: bool = True  # put the rendered frame in each record (for logging)

    def __post_init__(self):
        if isinstance(self.steps, bool) or not isinstance(self.steps, (int, np.integer)) or not 1 <= self.steps <= MAX_STEPS:
            raise ConfigError(f"steps must be an int in [1, {MAX_STEPS}], got {self.steps!r}")
        if self.converge_px <= 0 or self.hold_steps < 1:
            raise ConfigError("converge_px must be > 0 and hold_steps >= 1")


@dataclass
class StepRecord:
    step: int
    time: float
    frame: np.ndarray | None
    track: Track | None
    mode: str  # tracker mode ("align" | "predict" | "lost"), or "fault"
    features: np.ndarray  # (4, 2) corners the controller used
    gt_features: np.ndarray  # (4, 2) where those corners truly are
    desired: np.ndarray  # (4, 2) s*
    error_px: float  # ground-truth mean corner error to s*
    tracker_error_px: float  # mean distance between tracked and true corners
    occlusion: float  # true occlusion fraction
    twist: np.ndarray  # (6,) camera frame
    qdot: np.ndarray
    q: np.ndarray
    camera: CameraPose
    gain: float
    saturated: bool
    limit_blocked: tuple[int, ...]
    fault: str | None
    timings: dict[str, float]  # ms per stage
    people: list = field(default_factory=list)  # (feet position, orientation) of each person
    arm: tuple | None = None  # (positions (k, 3), orientations (k, 3, 3)) of the arm's meshes (Scene.arm_meshes)


def loop_tracker(tracker: str, settings: dict) -> Tracker | None:
    """The closed loop's tracker by name with its settings (None: the ground_truth oracle). Built
    before the scene, so a bad name or setting costs no rendering."""
    if tracker not in LOOP_TRACKERS:
        raise choice_error("tracker", tracker, LOOP_TRACKERS)
    if tracker == "ground_truth":
        if settings:
            raise ConfigError(f"ground_truth takes no tracker settings, got {sorted(settings)}")
        return None
    return make_tracker(tracker, **settings)


class ServoLoop:
    """One closed-loop episode of a scenario with the arm mount and a named tracker."""

    def __init__(self, scenario: Scenario, tracker: str = "deep_lk", config: LoopConfig = LoopConfig(), **tracker_config):
        if scenario.mount != "arm":
            raise ConfigError(f"the closed loop needs mount='arm', got {scenario.mount!r}")
        self.tracker = loop_tracker(tracker, tracker_config)
        self.scenario, self.tracker_name, self.config = scenario, tracker, config
        self.scene = Scene(scenario)
        self.renderer = Renderer(self.scene)
        lower, upper, qdot_max = self.scene.joint_limits()
        self.limits = ArmLimits(qdot_max=qdot_max, q_lower=lower, q_upper=upper)
        # desired flag corners: the target seen from the reference pose (centred, at the standoff)
        ref_pos, ref_R = self.scene.reference_pose()
        self.flag_desired = self.renderer.project(CameraPose(ref_R, ref_pos), self.renderer.target_corners_world())
        self.desired_depth = float(scenario.standoff)

    def _pinhole(self, pts: np.ndarray) -> np.ndarray:
        """Image points with the lens distortion taken out, as a calibrated camera would give IBVS its features
        (the interaction matrix holds for a pinhole); unchanged for a camera without distortion."""
        dist = self.renderer.sensor.distortion
        return undistort_points(self.renderer.K, dist, pts) if dist else pts

    def __iter__(self) -> Iterator[StepRecord]:
        return self.run()

    def run(self) -> Iterator[StepRecord]:
        scene, r, cfg = self.scene, self.renderer, self.config
        flag0 = roi0 = desired = controller = None
        for step in range(cfg.steps):
            timings: dict[str, float] = {}
            t0 = time.perf_counter()
            frame = r.rgb()
            timings["render"] = 1e3 * (time.perf_counter() - t0)
            t0 = time.perf_counter()
            gt: GroundTruth = r.ground_truth(occlusion=True)
            timings["ground_truth"] = 1e3 * (time.perf_counter() - t0)
            if step == 0:
                flag0 = gt.corners
                roi = roi_from_corners(flag0)
                roi0 = roi_corners(roi)
                desired = r.transfer(flag0, self.flag_desired, roi0)
                controller = IBVSController(r.K, self._pinhole(desired), self.desired_depth, cfg.ibvs)
            gt_features = r.transfer(flag0, gt.corners, roi0)
            fault, track = None, None
            t0 = time.perf_counter()
            if step == 0 and self.tracker is not None:
                try:  # without a template there is nothing to servo on: a failed init ends the run
                    init_track = self.tracker.init(frame, roi)
                except Exception as exc:  # any cause: the run cannot go on, and says why
                    raise StateError(f"tracker {self.tracker_name!r} could not start on the first frame (ROI {roi}): "
                                     f"{exc}") from exc
            try:
                if self.tracker is None:
                    features, mode = gt_features, "align"
                else:
                    track = init_track if step == 0 else self.tracker.update(frame)
                    features, mode = track.corners, track.mode
                    if not np.all(np.isfinite(features)):
                        raise FloatingPointError("tracker returned non-finite corners")
            except Exception as exc:  # noqa: BLE001 - a tracker fault must not crash the run: stop the arm and record it
                fault, features, mode = f"{type(exc).__name__}: {exc}", gt_features * np.nan, "fault"
            timings["track"] = 1e3 * (time.perf_counter() - t0)
            t0 = time.perf_counter()
            if fault is None:
                ctrl = controller.compute(self._pinhole(features), np.full(4, gt.target_depth), mode)
                twist, gain, sat = ctrl.twist, ctrl.gain, ctrl.saturated
            else:
                twist, gain, sat = np.zeros(6), 0.0, False
            cmd = twist_to_joint_velocities(scene.camera_jacobian(), camera_twist_to_world(gt.camera.R, twist),
                                            scene.joint_positions, self.limits)
            timings["control"] = 1e3 * (time.perf_counter() - t0)
            record = StepRecord(
                step=step, time=scene.time, frame=frame if cfg.keep_frames else None, track=track, mode=mode,
                features=features, gt_features=gt_features, desired=desired,
                error_px=float(np.linalg.norm(gt_features - desired, axis=1).mean()),
                tracker_error_px=float(np.linalg.norm(features - gt_features, axis=1).mean()) if fault is None else float("nan"),
                occlusion=gt.occlusion, twist=twist, qdot=cmd.qdot, q=gt.joint_positions, camera=gt.camera, gain=gain,
                saturated=sat or cmd.velocity_saturated, limit_blocked=cmd.limit_blocked, fault=fault, timings=timings,
                people=scene.people_poses(), arm=scene.arm_poses())
            t0 = time.perf_counter()
            scene.advance(cmd.qdot)
            timings["physics"] = 1e3 * (time.perf_counter() - t0)
            yield record


def summarize_run(records: list[StepRecord], config: LoopConfig) -> dict:
    """The run's JSON summary: convergence from ground truth, occlusion behaviour, stage timings."""
    err = np.array([r.error_px for r in records])
    below = err < config.converge_px
    steps_to_converge = None
    run = 0
    for i, b in enumerate(below):
        run = run + 1 if b else 0
        if run >= config.hold_steps:
            steps_to_converge = i - config.hold_steps + 1
            break
    occluded = np.array([r.occlusion > 0 for r in records])
    modes = [r.mode for r in records]
    stages = sorted({k for r in records for k in r.timings})
    timing = {k: {"median_ms": float(np.median([r.timings.get(k, 0.0) for r in records])),
                  "mean_ms": float(np.mean([r.timings.get(k, 0.0) for r in records]))} for k in stages}
    step_ms = np.array([sum(r.timings.values()) for r in records])
    return {
        "converged": steps_to_converge is not None,
        "steps_to_converge": steps_to_converge,
        "seconds_to_converge": None if steps_to_converge is None else float(records[steps_to_converge].time),
        "final_error_px": float(err[-1]),
        "min_error_px": float(err.min()),
        "max_error_px_during_occlusion": float(err[occluded].max()) if occluded.any() else None,
        "occluded_steps": int(occluded.sum()),
        "lost_steps": int(sum(m == "lost" for m in modes)),
        "predict_steps": int(sum(m == "predict" for m in modes)),
        "fault_steps": int(sum(m == "fault" for m in modes)),
        "faults": sorted({r.fault for r in records if r.fault}),
        "saturated_steps": int(sum(r.saturated for r in records)),
        "limit_blocked_steps": int(sum(bool(r.limit_blocked) for r in records)),
        "median_tracker_error_px": float(np.nanmedian([r.tracker_error_px for r in records])),
        "steps": len(records),
        "timing": timing,
        "steps_per_second": float(1e3 / np.mean(step_ms)),
    }
