"""One step of the closed loop, and the two drivers that run the steps: `sequential` (capture, track, control, physics
one after another) and `pipelined` (the tracker on frame k in a second thread while the physics steps and frame k + 1
renders). The step's phases are written once here, so that the drivers differ only in what overlaps what.

The drivers take the ServoLoop (the agent: tracker, law, feature filter, safety) and call its phases; they do not
import it, so that hvs_sim.servo.loop imports this module and never the reverse."""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from hvs_sim.control.arm import JointCommand
from hvs_sim.errors import StateError
from hvs_sim.servo.parts import Capture, Episode, Measured, Stopwatch, lap
from hvs_sim.servo.records import StepRecord
from hvs_sim.servo.teach import corners_in_view
from hvs_sim.tracking import Track

PIPELINE_IDLE = ("render", "ground_truth", "physics")  # a pipelined step's stages of the next frame: 0 after the last


def sequential(loop) -> Iterator[StepRecord]:
    """Capture, track, control, physics one after another: a frame's command acts at once. wall_ms runs from the end of
    the step before, so what the consumer does with a record (the recording, the CSV) counts in the next."""
    wall, cap = Stopwatch(), capture(loop)
    ep = loop.step_zero(cap)
    for step in range(loop.config.steps):
        timings, watch = dict(cap.timings), Stopwatch()
        truth, first = begin(loop, ep, cap, step)
        seen = measure(loop, truth, cap.obs.frame, first)
        timings["track"] = watch.ms()
        seen, ctrl, cmd = act(loop, ep, cap, seen, step, timings, cap.depths_ms)
        with lap(timings, "physics"):
            loop.task.advance(cmd.qdot)
        yield record(loop, step, cap, ep, seen, ctrl, cmd, timings, wall_ms=wall.lap())
        if ep.aborted is not None:
            return
        if step + 1 < loop.config.steps:
            cap = capture(loop)


def pipelined(loop, pool: ThreadPoolExecutor) -> Iterator[StepRecord]:
    """Frame k tracked in `pool` while this thread steps the physics with frame k − 1's command and captures frame
    k + 1. A step's render, ground_truth and physics (and the true depths in control) are therefore those of the next
    frame (0 after the last), its track the init's time here plus the tracker's own (Track.ms), and wall_ms runs from
    the end of the step before, so the consumer's time counts in the next step."""
    qdot_due = np.zeros(len(loop.arm.limits.qdot_max))  # the command that acts this step: the step before's
    wall, cap = Stopwatch(), capture(loop)
    ep = loop.step_zero(cap)
    for step in range(loop.config.steps):
        watch = Stopwatch()
        truth, first = begin(loop, ep, cap, step)  # no track is in flight between steps: the switch may happen here
        pending = pool.submit(track, loop, cap.obs.frame, first) if loop.tracker is not None else None
        init_ms = watch.ms()
        timings, nxt, depths_ms = dict.fromkeys(PIPELINE_IDLE, 0.0), None, 0.0
        if step + 1 < loop.config.steps:  # meanwhile: physics with the command due, then the next frame
            with lap(timings, "physics"):
                loop.task.advance(qdot_due)
            nxt = capture(loop)
            timings.update(nxt.timings)
            depths_ms = nxt.depths_ms
        seen = measure(loop, truth, pending=pending)
        timings["track"] = init_ms + (seen.track.ms if seen.track is not None else 0.0)
        seen, ctrl, cmd = act(loop, ep, cap, seen, step, timings, depths_ms)  # at the next step's configuration
        yield record(loop, step, cap, ep, seen, ctrl, cmd, timings, wall_ms=wall.lap())
        if ep.aborted is not None:
            return
        if nxt is None:  # the last step
            return
        qdot_due, cap = cmd.qdot, nxt


def begin(loop, ep: Episode, cap: Capture, step: int) -> tuple[np.ndarray, Track | None]:
    """The step's start: the switch to the near-goal template when due, where the features truly are (the target's
    true corners carried into the template's box), and at step 0 the tracker's start (its own first track, if any)."""
    if ep.grow_from is not None:
        loop.switch_to_near_goal(ep, step)
    truth = loop.renderer.transfer(ep.flag0, cap.truth.corners, ep.roi0)
    return truth, (loop.start_tracker(ep, truth) if step == 0 else None)


def act(loop, ep: Episode, cap: Capture, seen: Measured, step: int, timings: dict[str, float],
        depths_ms: float) -> tuple[Measured, object, JointCommand]:
    """Control on the step's features (the true depths' time counted as control), then whether the near-goal switch
    is due."""
    with lap(timings, "control"):
        seen, ctrl, cmd = loop.control(ep, cap.obs, cap.depths, seen, step)  # the truth stays here
        loop.templates.due(ep, seen)
    timings["control"] += depths_ms
    return seen, ctrl, cmd


def capture(loop) -> Capture:
    """Everything a step reads from the scene at its state: the frame and the truth that grades it."""
    task, timings = loop.task, dict[str, float]()
    with lap(timings, "render"):
        obs = task.observe(frame=loop.renders_frames)
    with lap(timings, "ground_truth"):
        truth = task.truth(occlusion=loop.config.evaluate)
    watch = Stopwatch()
    depths = loop.true_depths() if loop.ibvs_config.depth == "true" else None  # only when asked
    depths_ms = watch.ms()
    return Capture(obs, truth, task.scene.people_poses(), task.scene.arm_poses(), depths, timings, depths_ms)


def track(loop, frame: np.ndarray | None, first: Track | None) -> Track:
    """The tracker's corners for a frame (`first`: the init's own track of step 0, when it has one)."""
    if first is None and frame is None:
        raise StateError("the tracker has no frame: the loop rendered none (ServoLoop.renders_frames)")
    out = first if first is not None else loop.tracker.update(frame)
    if not np.all(np.isfinite(out.corners)):
        raise FloatingPointError("tracker returned non-finite corners")
    return out


def measure(loop, truth: np.ndarray, frame: np.ndarray | None = None, first: Track | None = None,
            pending: Future | None = None) -> Measured:
    """The step's corners: the tracker's, here or from the tracking thread (`pending`), else the truth's. A tracker
    fault must not crash the run: it is recorded, and control holds the arm."""
    try:
        if loop.tracker is None:  # the oracle's features; a law on the images or a policy reads none
            return Measured(None, truth, truth, truth, "align", None)
        got = pending.result() if pending is not None else track(loop, frame, first)
        return Measured(got, truth, got.corners, got.corners, got.mode, None)
    except Exception as exc:  # noqa: BLE001 - any tracker fault
        lost = truth * np.nan
        return Measured(None, truth, lost, lost, "fault", f"{type(exc).__name__}: {exc}")


def record(loop, step: int, cap: Capture, ep: Episode, seen: Measured, ctrl, cmd: JointCommand,
           timings: dict[str, float], wall_ms: float | None = None) -> StepRecord:
    """The step as logged and graded: what the loop did, beside the truth it did not see."""
    obs, truth, res = cap.obs, seen.truth, loop.resolved
    twist, gain, sat, sv = ((ctrl.twist, ctrl.gain, ctrl.saturated, ctrl.singular_values) if ctrl is not None
                            else (np.zeros(6), 0.0, False, np.zeros(0)))
    graded = seen.fault is None and (loop.tracker is not None or loop.oracle)
    return StepRecord(
        step=step, time=obs.time, frame=obs.frame if loop.config.keep_frames else None, track=seen.track,
        mode=seen.mode, features=seen.features, gt_features=truth, desired=ep.desired,
        error_px=float(np.linalg.norm(truth - ep.desired, axis=1).mean()),
        tracker_error_px=float(np.linalg.norm(seen.tracked - truth, axis=1).mean()) if graded else float("nan"),
        occlusion=cap.truth.occlusion, twist=twist, qdot=cmd.qdot, q=obs.joints, camera=obs.camera, gain=gain,
        saturated=sat or cmd.velocity_saturated, limit_blocked=cmd.limit_blocked, fault=seen.fault,
        timings=timings, pose_error=cap.truth.pose_error, singular_values=sv,
        dofs=(ctrl.dofs or res.dofs) if ctrl is not None else res.dofs, damping=loop.ibvs_config.damping,
        feature_filter=res.filter_alpha,
        filter_restarted=ep.feature_filter is not None and ep.feature_filter.restarted,
        template=(res.template_from, int(ep.inset), res.goal_frames),
        target_in_view=corners_in_view(cap.truth.corners, loop.scenario.camera),
        controlled_pose_error=loop.controlled_pose_error(cap.truth.pose_error), people=cap.people, arm=cap.arm,
        wall_ms=wall_ms, held_because=ep.held_because, aborted=ep.aborted)
