"""The closed loop: render → track → control → step physics, one record per step.

Logging and plots only read the records. A tracker exception or non-finite output stops the arm
for that step (zero twist) and is written into the record; the loop goes on.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from hvs_sim.camera_model import undistort_points
from hvs_sim.control.arm import ArmLimits, camera_twist_to_world, twist_to_joint_velocities
from hvs_sim.control.ibvs import (
    CONTROLLERS,
    DOF_NAMES,
    TRACKED_6DOF_DAMPING,
    IBVSConfig,
    IBVSController,
    condition_number,
    dofs_for,
    matrix_rank,
)
from hvs_sim.control.pbvs import PBVSController
from hvs_sim.errors import ConfigError, HvsError, StateError, choice_error
from hvs_sim.render.camera import CameraPose
from hvs_sim.render.renderer import GroundTruth, Renderer
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.scene.world import Scene
from hvs_sim.tracking import TRACKER_NAMES, Track, Tracker, make_tracker
from hvs_sim.tracking.frames import roi_corners, roi_from_corners

LOOP_TRACKERS = ("ground_truth",) + TRACKER_NAMES
MAX_STEPS = 100_000
IN_VIEW_MARGIN_PX = 2.0  # the target's corners must be this far inside the image at the start
# pose bound for `converged`: a 15 cm target at 0.8 m pins lateral translation and pitch/yaw only
# weakly (a 1° tilt traded against 14 mm of sideways shift moves its corners by ~0.1 px), so the
# bound is stated beside the 0.5 px image threshold rather than derived from it
CONVERGE_MM, CONVERGE_DEG = 10.0, 1.0


@dataclass(frozen=True)
class LoopConfig:
    steps: int = 300
    converge_px: float = 0.5  # mean corner error to s* that counts as converged ...
    hold_steps: int = 10  # ... when held this many consecutive steps
    ibvs: IBVSConfig = field(default_factory=IBVSConfig)
    keep_frames: bool = True  # put the rendered frame in each record (for logging)
    controller: str = "ibvs"  # the servo law: "ibvs" (v = −λ L⁺ e) or "pbvs" (pbvs.py); both use `ibvs`'s gains
    # and the pose must be within these of the reference pose, in the DOFs controlled (ground truth)
    converge_mm: float = CONVERGE_MM
    converge_deg: float = CONVERGE_DEG

    def __post_init__(self):
        if self.controller not in CONTROLLERS:
            raise choice_error("controller", self.controller, CONTROLLERS)
        if not (self.converge_mm > 0 and self.converge_deg > 0):
            raise ConfigError(f"converge_mm and converge_deg must be > 0, got {self.converge_mm}, {self.converge_deg}")
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
    # the camera's pose error to the reference pose (Scene.pose_error: x, y, z mm; about x, y, z deg), truth
    pose_error: np.ndarray = field(default_factory=lambda: np.zeros(6))
    singular_values: np.ndarray = field(default_factory=lambda: np.zeros(0))  # of the controlled columns of L
    dofs: tuple[str, ...] = DOF_NAMES  # the DOFs the controller commands
    target_in_view: bool = True  # all four true target corners inside the image
    damping: float = 0.0  # the IBVS damping the loop used (IBVSConfig.damping, resolved)
    controlled_pose_error: tuple[float, float] = (0.0, 0.0)  # (mm, deg) of pose_error in those DOFs
    people: list = field(default_factory=list)  # (feet position, orientation) of each person
    arm: tuple | None = None  # (positions (k, 3), orientations (k, 3, 3)) of the arm's meshes (Scene.arm_meshes)

    @property
    def condition(self) -> float | None:
        """Condition number of the controlled columns of L (None: no control this step, or rank-deficient)."""
        return condition_number(self.singular_values)

    @property
    def rank(self) -> int | None:
        return matrix_rank(self.singular_values)


def corners_in_view(px: np.ndarray, camera, margin: float = 0.0) -> bool:
    """Whether all points (pixels) are finite and at least `margin` inside a camera's image."""
    hi = np.array([camera.width - 1, camera.height - 1]) - margin
    return bool(np.all(np.isfinite(px)) and np.all((px >= margin) & (px <= hi)))


def check_start_in_view(scene: Scene, renderer: Renderer) -> None:
    """ConfigError unless all four target corners are inside the image from the scenario's start pose."""
    start_pos, start_R = scene.start_pose()
    px = renderer.project(CameraPose(start_R, start_pos), renderer.target_corners_world())
    cam = scene.scenario.camera
    if not corners_in_view(px, cam, IN_VIEW_MARGIN_PX):
        raise ConfigError(f"from the start offset {scene.scenario.start_offset_text} the target is not fully in view "
                          f"(its corners at {np.round(px, 1).tolist()} px in a {cam.width}×{cam.height} image): "
                          "give a smaller offset")


def check_start_pose(scenario: Scenario) -> None:
    """ConfigError when the arm cannot reach the scenario's start pose or the target is not fully in view
    from it (builds the scene, renders nothing)."""
    scene = Scene(scenario)
    check_start_in_view(scene, Renderer(scene))


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
        check_start_in_view(self.scene, self.renderer)
        # the DOFs the features observe: ground truth and a homography tracker give perspective corners
        self.warp = "homography" if self.tracker is None else self.tracker.warp
        self.dofs = tuple(config.ibvs.dofs or dofs_for(self.warp))
        damping = config.ibvs.damping
        if damping is None:  # exact features need none; tracked ones on six DOF do (IBVSConfig.damping)
            tracked_6dof = self.tracker is not None and len(self.dofs) == 6 and config.controller == "ibvs"
            damping = TRACKED_6DOF_DAMPING if tracked_6dof else 0.0  # PBVS inverts no L: nothing to damp
        self.ibvs_config = dataclasses.replace(config.ibvs, damping=damping)

    def controlled_pose_error(self, pose_error: np.ndarray) -> tuple[float, float]:
        """(mm, deg) of the pose error in the DOFs this loop controls."""
        cols = [DOF_NAMES.index(d) for d in self.dofs]
        lin, ang = [c for c in cols if c < 3], [c for c in cols if c >= 3]
        return float(np.linalg.norm(pose_error[lin])), float(np.linalg.norm(pose_error[ang]))

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
                law = IBVSController if cfg.controller == "ibvs" else PBVSController
                controller = law(r.K, self._pinhole(desired), self.desired_depth, self.ibvs_config, self.dofs)
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
            ctrl = None
            if fault is None:
                try:  # PBVS cannot take a pose from a degenerate quad: like a tracker fault, stop the arm and record it
                    ctrl = controller.compute(self._pinhole(features), np.full(4, gt.target_depth), mode)
                except HvsError as exc:
                    fault, mode = f"{type(exc).__name__}: {exc}", "fault"
            if ctrl is not None:
                twist, gain, sat, sv = ctrl.twist, ctrl.gain, ctrl.saturated, ctrl.singular_values
            else:
                twist, gain, sat, sv = np.zeros(6), 0.0, False, np.zeros(0)
            cmd = twist_to_joint_velocities(scene.camera_jacobian(), camera_twist_to_world(gt.camera.R, twist),
                                            scene.joint_positions, self.limits)
            timings["control"] = 1e3 * (time.perf_counter() - t0)
            pose_err = scene.pose_error()
            record = StepRecord(
                step=step, time=scene.time, frame=frame if cfg.keep_frames else None, track=track, mode=mode,
                features=features, gt_features=gt_features, desired=desired,
                error_px=float(np.linalg.norm(gt_features - desired, axis=1).mean()),
                tracker_error_px=float(np.linalg.norm(features - gt_features, axis=1).mean()) if fault is None else float("nan"),
                occlusion=gt.occlusion, twist=twist, qdot=cmd.qdot, q=gt.joint_positions, camera=gt.camera, gain=gain,
                saturated=sat or cmd.velocity_saturated, limit_blocked=cmd.limit_blocked, fault=fault, timings=timings,
                pose_error=pose_err, singular_values=sv, dofs=self.dofs, damping=self.ibvs_config.damping,
                target_in_view=corners_in_view(gt.corners, self.scenario.camera),
                controlled_pose_error=self.controlled_pose_error(pose_err), people=scene.people_poses(),
                arm=scene.arm_poses())
            t0 = time.perf_counter()
            scene.advance(cmd.qdot)
            timings["physics"] = 1e3 * (time.perf_counter() - t0)
            yield record


def summarize_run(records: list[StepRecord], config: LoopConfig) -> dict:
    """The run's JSON summary: convergence from ground truth, occlusion behaviour, stage timings.

    Converged: for `hold_steps` consecutive steps the image error is under `converge_px` AND the
    camera's pose error, in the DOFs the controller commands, is under `converge_mm` / `converge_deg`
    (a 4-DOF loop that centres a tilted target by sliding sideways has a small image error but not the pose)."""
    err = np.array([r.error_px for r in records])
    ctrl_pose = np.array([r.controlled_pose_error for r in records])
    below = (err < config.converge_px) & (ctrl_pose[:, 0] < config.converge_mm) & (ctrl_pose[:, 1] < config.converge_deg)
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
    final = records[-1]
    conds = [r.condition for r in records if r.condition is not None]
    ranks = [r.rank for r in records if r.rank is not None]
    return {
        "controller": config.controller,
        "damping": records[0].damping,
        "controlled_dofs": list(final.dofs),
        "pose_bound": {"mm": config.converge_mm, "deg": config.converge_deg,
                       "applies_to": list(final.dofs),
                       "note": "converged = image error under converge_px and the pose error in these DOFs under "
                               "the bound, both held hold_steps steps"},
        "final_pose_error_mm": float(np.linalg.norm(final.pose_error[:3])),
        "final_pose_error_deg": float(np.linalg.norm(final.pose_error[3:])),
        "final_pose_error": dict(zip(("x_mm", "y_mm", "z_mm", "about_x_deg", "about_y_deg", "about_z_deg"),
                                     (float(v) for v in final.pose_error))),
        "final_controlled_pose_error_mm": float(final.controlled_pose_error[0]),
        "final_controlled_pose_error_deg": float(final.controlled_pose_error[1]),
        "camera_path_m": float(sum(np.linalg.norm(b.camera.t - a.camera.t) for a, b in pairwise(records))),
        "target_out_of_view_steps": int(sum(not r.target_in_view for r in records)),
        "max_condition_number": max(conds) if conds else None,
        "min_rank": min(ranks) if ranks else None,
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
