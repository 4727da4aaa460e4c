"""What a run leaves: one StepRecord per step (what the loop did beside the truth it did not see), and the run's
summary accumulated step by step (RunStats) without keeping the records: convergence from ground truth, occlusion
behaviour, the safety rule, stage timings. The loop (servo/loop.py) yields the records; the runner, the benchmarks
and the gym env feed them to RunStats."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from hvs_sim.control.features import condition_number, matrix_rank
from hvs_sim.control.laws.ibvs import DOF_NAMES
from hvs_sim.errors import StateError
from hvs_sim.render.camera import CameraPose
from hvs_sim.tracking import Track

if TYPE_CHECKING:
    from hvs_sim.servo.config import LoopConfig

MODES = ("align", "predict", "lost", "fault")  # a record's mode, in the order its code (index) is plotted and stored


REAPPEAR_OCCLUSION, HIDDEN_OCCLUSION = 0.1, 0.5  # the target "reappears" under 10 % hidden after ≥ 50 % hidden
REACQUIRED_PX = 2.0  # re-acquired: aligned again with the tracked corners this close to the truth
# a runaway: the camera ended this much further from the goal than it started (or the envelope stopped it)
RUNAWAY_MM = 50.0


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
    feature_filter: float = 0.0  # the feature filter's α the loop used (LoopConfig.feature_filter, resolved; 0 = off)
    filter_restarted: bool = False  # the feature filter restarted at this measurement (FeatureFilter.gate_px)
    # where the template came from, its inset and the frames averaged into a goal image (LoopConfig, resolved)
    template: tuple[str, int, int | None] = ("start", 0, None)
    # wall ms of the step when its stages overlap (LoopConfig.pipeline): from the end of the step before (so the
    # consumer's time, e.g. logging, counts in the next step) to this record; a pipelined step's render,
    # ground_truth and physics are those of the next frame, made while this one was tracked (0 on the last step).
    # None: the stages ran one after another and their sum is the step's time
    wall_ms: float | None = None
    controlled_pose_error: tuple[float, float] = (0.0, 0.0)  # (mm, deg) of pose_error in those DOFs
    people: list = field(default_factory=list)  # (feet position, orientation) of each person
    # the safety rule (LoopConfig.safety): why it held the arm this step (None: the law's twist was followed), and
    # why the episode ended here, when the next command would have left the workspace envelope
    held_because: str | None = None
    aborted: str | None = None
    arm: tuple | None = None  # (positions (k, 3), orientations (k, 3, 3)) of the arm's meshes (Scene.arm_meshes)

    @property
    def condition(self) -> float | None:
        """Condition number of the controlled columns of L (None: no control this step, or rank-deficient)."""
        return condition_number(self.singular_values)

    @property
    def rank(self) -> int | None:
        return matrix_rank(self.singular_values)


class RunStats:
    """A run's summary, accumulated step by step in arrays sized for `config.steps` when the run starts,
    so that memory does not grow with the steps taken (a 100 000-step run keeps no records)."""

    def __init__(self, config: LoopConfig, near_goal: Callable[[int | None], dict | None] | None = None) -> None:
        """near_goal: the loop's near_goal_plan (called with the switch step at summary time); None: the summary
        tells the near-goal template from the config and the records."""
        n = config.steps
        self.config, self.n, self.near_goal = config, 0, near_goal
        self.time, self.error_px, self.tracker_error_px, self.occlusion = (np.full(n, np.nan) for _ in range(4))
        self.controlled = np.full((n, 2), np.nan)
        self.camera_t = np.full((n, 3), np.nan)  # the camera's position (m), truth: how far it moved while hidden
        self.held = 0  # steps the safety rule held the arm
        self.held_because: dict[str, int] = {}
        self.aborted: str | None = None
        self.mode = np.zeros(n, np.int8)
        self.step_ms = np.zeros(n)
        self.timings: dict[str, np.ndarray] = {}
        self.faults: set[str] = set()
        self.saturated = self.limit_blocked = self.out_of_view = self.filter_restarts = 0
        self.path_m = 0.0
        self.switched_at: int | None = None  # the first step on another template than step 0's (near_goal)
        self.switched_inset: int | None = None  # that template's inset (px)
        self.max_condition: float | None = None
        self.min_rank: int | None = None
        self.first: StepRecord | None = None
        self.last: StepRecord | None = None

    def add(self, r: StepRecord) -> None:
        if self.n >= len(self.time):
            raise StateError(f"RunStats holds {len(self.time)} steps (LoopConfig.steps); got one more")
        k = self.n
        self.time[k], self.error_px[k], self.tracker_error_px[k] = r.time, r.error_px, r.tracker_error_px
        self.occlusion[k], self.controlled[k] = r.occlusion, r.controlled_pose_error
        self.camera_t[k] = r.camera.t
        if r.held_because is not None:
            self.held += 1
            self.held_because[r.held_because] = self.held_because.get(r.held_because, 0) + 1
        self.aborted = self.aborted or r.aborted
        self.mode[k] = MODES.index(r.mode) if r.mode in MODES else MODES.index("fault")
        for stage, ms in r.timings.items():
            self.timings.setdefault(stage, np.zeros(len(self.time)))[k] = ms
        self.step_ms[k] = sum(r.timings.values()) if r.wall_ms is None else r.wall_ms
        if r.fault:
            self.faults.add(r.fault)
        self.saturated += bool(r.saturated)
        self.limit_blocked += bool(r.limit_blocked)
        self.out_of_view += not r.target_in_view
        self.filter_restarts += bool(r.filter_restarted)
        if self.last is not None and self.first is not None:
            self.path_m += float(np.linalg.norm(r.camera.t - self.last.camera.t))
            if self.switched_at is None and r.template != self.first.template:
                self.switched_at, self.switched_inset = r.step, r.template[1]
        if r.condition is not None:
            self.max_condition = max(self.max_condition or 0.0, r.condition)
        if r.rank is not None:
            self.min_rank = r.rank if self.min_rank is None else min(self.min_rank, r.rank)
        light = dataclasses.replace(r, frame=None, track=None, people=[], arm=None)  # no image held
        self.first = self.first or light
        self.last = light
        self.n += 1

    def series(self) -> dict[str, np.ndarray]:
        """Per-step time, errors, occlusion and mode of the steps so far (for figures)."""
        n = self.n
        return {"time": self.time[:n], "error_px": self.error_px[:n], "tracker_error_px": self.tracker_error_px[:n],
                "occlusion": self.occlusion[:n], "predict": self.mode[:n] == MODES.index("predict"),
                "pose_mm": self.controlled[:n, 0], "pose_deg": self.controlled[:n, 1]}

    def _why_not(self, err_px: float, pose: np.ndarray) -> str:
        """Why the run's end is not within the bounds, bound by bound ("pose error 15.4 mm > 10 mm; image 0.09 px ok")."""
        c = self.config
        parts = [f"image {err_px:.2f} px " + ("ok" if err_px < c.converge_px else f"> {c.converge_px:g} px"),
                 f"pose error {pose[0]:.1f} mm " + ("ok" if pose[0] < c.converge_mm else f"> {c.converge_mm:g} mm"),
                 f"{pose[1]:.2f}° " + ("ok" if pose[1] < c.converge_deg else f"> {c.converge_deg:g}°")]
        failing = [p for p in parts if not p.endswith("ok")]
        if not failing:
            return f"the bounds were not all met over the last {c.hold_steps} steps"
        return "; ".join(failing + [p for p in parts if p.endswith("ok")])


    def _occlusion_figures(self) -> dict:
        """What only an occlusion benchmark reports: how long the tracker took to re-acquire after the target
        reappeared (s; None when it never hid, NaN-free: `reacquired` says whether it did), and how far its estimate
        drifted while the target was hidden (max tracker error over steps ≥ HIDDEN_OCCLUSION hidden)."""
        n = self.n
        occ, terr, mode = self.occlusion[:n], self.tracker_error_px[:n], self.mode[:n]
        out: dict[str, float | bool | None] = {"seconds_to_reacquire": None, "reacquired": None,
                                               "max_tracker_error_while_hidden_px": None,
                                               "max_drift_while_hidden_mm": None}
        if not np.all(np.isfinite(occ)):
            return out
        hidden = np.flatnonzero(occ >= HIDDEN_OCCLUSION)
        if not len(hidden):
            return out
        out["max_drift_while_hidden_mm"] = self._drift_while_hidden_mm(occ >= HIDDEN_OCCLUSION)
        if not np.isfinite(terr).any():
            return out
        drift = terr[hidden]
        out["max_tracker_error_while_hidden_px"] = float(np.nanmax(drift)) if np.isfinite(drift).any() else None
        after = np.flatnonzero((np.arange(n) > hidden[-1]) & (occ < REAPPEAR_OCCLUSION))
        if not len(after):
            return out
        back = after[0]
        ok = np.flatnonzero((np.arange(n) >= back) & (mode == MODES.index("align")) & (terr <= REACQUIRED_PX))
        out["reacquired"] = bool(len(ok))
        if len(ok):
            out["seconds_to_reacquire"] = float(self.time[ok[0]] - self.time[back])
        return out

    def _drift_while_hidden_mm(self, hidden: np.ndarray) -> float:
        """How far the camera moved while the target was hidden: over each stretch of hidden steps, the largest
        distance (mm) from where the camera was when the stretch began (truth, for evaluation)."""
        worst, start = 0.0, None
        for k, h in enumerate(hidden):
            if not h:
                start = None
                continue
            start = k if start is None else start
            worst = max(worst, float(np.linalg.norm(self.camera_t[k] - self.camera_t[start])))
        return 1e3 * worst

    def summary(self) -> dict:
        """The run's JSON summary: convergence from ground truth, occlusion behaviour, stage timings.

        Converged: for `hold_steps` consecutive steps the image error is under `converge_px` AND the
        camera's pose error, in the DOFs the controller commands, is under `converge_mm` / `converge_deg`
        (a 4-DOF loop that centres a tilted target by sliding sideways has a small image error but not the pose)."""
        first, final = self.first, self.last
        if self.n == 0 or first is None or final is None:
            raise StateError("no steps to summarise")
        config, n = self.config, self.n
        err, ctrl_pose = self.error_px[:n], self.controlled[:n]
        below = (err < config.converge_px) & (ctrl_pose[:, 0] < config.converge_mm) & (ctrl_pose[:, 1] < config.converge_deg)
        steps_to_converge = None
        run = 0
        for i, b in enumerate(below):
            run = run + 1 if b else 0
            if run >= config.hold_steps:
                steps_to_converge = i - config.hold_steps + 1
                break
        held = bool(n >= config.hold_steps and below[n - config.hold_steps:].all() and self.aborted is None)
        occ = self.occlusion[:n]
        evaluated = bool(np.all(np.isfinite(occ)))
        occluded = occ > 0  # NaN (not evaluated) counts as not occluded; the occlusion figures are then None
        mode = self.mode[:n]
        count = {m: int(np.sum(mode == i)) for i, m in enumerate(MODES)}
        timing: dict[str, dict[str, float | str]] = {k: {"median_ms": float(np.median(v[:n])),
                                                         "mean_ms": float(np.mean(v[:n]))}
                  for k, v in sorted(self.timings.items())}
        step = self.step_ms[:n]
        timing["step"] = {"median_ms": float(np.median(step)), "mean_ms": float(np.mean(step)),  # as run: wall time
                          "first_ms": float(step[0])}  # step 0 holds the set-up (goal image, template, law)
        if not config.pipeline and n > 1:  # the stages one after another: what a step's wall time holds beyond them
            staged = sum(float(np.mean(v[1:n])) for v in self.timings.values())
            timing["other"] = {"mean_ms": float(np.mean(step[1:])) - staged,
                               "note": "after step 0, the step's wall time less its stages: the consumer's "
                                       "bookkeeping (CSV, progress bar, statistics) and the loop's own between stages"}
        tracker_err = self.tracker_error_px[:n]
        final_mm, initial_mm = (float(np.linalg.norm(r.pose_error[:3])) for r in (final, first))
        return {
            "controller": None if config.policy is not None else config.controller,
            "policy": config.policy,
            "damping": first.damping,
            "pipeline": config.pipeline,
            "template_from": first.template[0],
            "roi_inset_px": first.template[1],
            "near_goal": self._near_goal(),
            "goal_frames": first.template[2],
            "feature_filter": first.feature_filter,
            "feature_filter_restarts": self.filter_restarts,
            "controlled_dofs": list(final.dofs),
            "pose_bound": {"mm": config.converge_mm, "deg": config.converge_deg,
                           "applies_to": list(final.dofs),
                           "note": "converged = image error under converge_px and the pose error in these DOFs under "
                                   "the bound, both held hold_steps steps"},
            "final_pose_error_mm": final_mm,
            "final_pose_error_deg": float(np.linalg.norm(final.pose_error[3:])),
            "final_pose_error": dict(zip(("x_mm", "y_mm", "z_mm", "about_x_deg", "about_y_deg", "about_z_deg"),
                                         (float(v) for v in final.pose_error))),
            "final_controlled_pose_error_mm": float(final.controlled_pose_error[0]),
            "final_controlled_pose_error_deg": float(final.controlled_pose_error[1]),
            "camera_path_m": self.path_m,
            "target_out_of_view_steps": self.out_of_view,
            "max_condition_number": self.max_condition,
            "min_rank": self.min_rank,
            "converged": steps_to_converge is not None,
            # the bounds met over the run's last hold_steps steps (`converged`: met for hold_steps steps at some point)
            "held_to_end": held,
            "not_converged_because": (None if held else f"aborted: {self.aborted}" if self.aborted
                                      else self._why_not(err[-1], ctrl_pose[-1])),
            "initial_pose_error_mm": initial_mm,
            # the safety rule (LoopConfig.safety): why the episode was ended early, the steps it held the arm and why
            "aborted": self.aborted,
            "held_steps": self.held,
            "held_because": dict(sorted(self.held_because.items())),
            "runaway": self.aborted is not None or final_mm - initial_mm > RUNAWAY_MM,
            "initial_pose_error_deg": float(np.linalg.norm(first.pose_error[3:])),
            **self._occlusion_figures(),
            "steps_to_converge": steps_to_converge,
            "seconds_to_converge": None if steps_to_converge is None else float(self.time[steps_to_converge]),
            "final_error_px": float(err[-1]),
            "min_error_px": float(err.min()),
            "evaluated": evaluated,
            "max_error_px_during_occlusion": float(err[occluded].max()) if occluded.any() else None,
            "occluded_steps": int(occluded.sum()) if evaluated else None,
            "lost_steps": count["lost"],
            "predict_steps": count["predict"],
            "fault_steps": count["fault"],
            "faults": sorted(self.faults),
            "saturated_steps": self.saturated,
            "limit_blocked_steps": self.limit_blocked,
            "median_tracker_error_px": float(np.nanmedian(tracker_err)) if np.isfinite(tracker_err).any() else None,
            "steps": n,
            "timing": timing,
            "steps_per_second": float(1e3 / np.mean(self.step_ms[:n])),
        }


    def _near_goal(self) -> dict | None:
        if self.near_goal is not None:
            return self.near_goal(self.switched_at)
        c = self.config
        if c.near_goal_inset_px is None:
            return None
        return {"inset_px": self.switched_inset if isinstance(c.near_goal_inset_px, str) else c.near_goal_inset_px,
                "auto": isinstance(c.near_goal_inset_px, str), "within_px": c.near_goal_within_px,
                "scale": c.near_goal_scale, "off": None, "switched_at_step": self.switched_at,
                "note": "from the records alone (summarize_run without the loop): the step from which the grown "
                        "template's corners were the features (null: never switched); what the loop resolved (an "
                        "automatic growth that never switched, the scale, why it was off) is not in them"}


def summarize_run(records: list, config, loop=None) -> dict:
    """RunStats.summary of a list of records (see there); `loop`, the ServoLoop that made them, for its near-goal
    template as it resolved it."""
    stats = RunStats(dataclasses.replace(config, steps=max(len(records), 1)),
                     None if loop is None else loop.near_goal_plan)
    for r in records:
        stats.add(r)
    return stats.summary()
