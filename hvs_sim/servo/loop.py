"""The closed loop: render → track → control → step physics, one record per step (servo/records.py).

Logging and plots only read the records. A tracker exception or non-finite output stops the arm
for that step (zero twist) and is written into the record; the loop goes on.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import torch

from hvs_sim import plugins
from hvs_sim.control.arm import ArmDriver, JointCommand
from hvs_sim.control.feature_filter import FeatureFilter
from hvs_sim.control.ibvs import (
    CONTROLLERS,
    DOF_NAMES,
    ControlOutput,
    IBVSController,
    bound_twist,
)
from hvs_sim.control.pbvs import PBVSController
from hvs_sim.control.protocol import ControlInput, PolicyInput, scale_depths
from hvs_sim.control.safety import Envelope, SafetyGate
from hvs_sim.errors import ConfigError, HvsError, InputError, StateError
from hvs_sim.render.camera import CameraPose
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.scene.world import Scene
from hvs_sim.sensor import distort_points, undistort_points
from hvs_sim.servo.config import IN_VIEW_MARGIN_PX, LoopConfig
from hvs_sim.servo.parts import (
    NEAR_GOAL_AUTO,
    Capture,
    Episode,
    Measured,
    Stopwatch,
    Template,
    frozen,
    lap,
)
from hvs_sim.servo.plan import check_combination, loop_tracker, resolve, working_scale
from hvs_sim.servo.records import StepRecord
from hvs_sim.servo.teach import (
    box_in_view,
    check_start_in_view,
    corners_in_view,
    default_inset,
    goal_image,
    near_goal_growth,
)
from hvs_sim.tracking import Track, make_tracker
from hvs_sim.tracking.frames import inset_roi, roi_corners, roi_from_corners
from hvs_sim.tracking.warp import apply as apply_warp
from hvs_sim.tracking.warp import perspective_transform


class ServoLoop:
    """One closed-loop episode of a scenario with the arm mount and a named tracker."""

    def __init__(self, scenario: Scenario, tracker: str = "deep_lk", config: LoopConfig | None = None, **tracker_config):
        config = LoopConfig() if config is None else config
        if scenario.mount != "arm":
            raise ConfigError(f"the closed loop needs mount='arm', got {scenario.mount!r}")
        # an outside law or policy, built before the scene (and checked with the tracker's name before the tracker)
        self.law = None if config.controller in CONTROLLERS else plugins.build("controller", config.controller)
        self.policy = None if config.policy is None else plugins.build("policy", config.policy)
        self.image_law = config.controller == "dvs" or (self.law is not None and not self.law.uses_features)
        check_combination(tracker, config, self.image_law)
        self.tracker = loop_tracker(tracker, tracker_config)
        self.scenario, self.tracker_name, self.config = scenario, tracker, config
        self.oracle = tracker == plugins.GROUND_TRUTH
        self.resolved = resolve(tracker, config, self.tracker, self.law, self.policy)
        self.near_goal_tracker = None  # the tracker on the near-goal template, when it is another (near_goal_scale)
        if self.resolved.near_goal_scale is not None:
            self.near_goal_tracker = make_tracker(tracker, **{**tracker_config, "scale": self.resolved.near_goal_scale})
        self.near_goal_growth: int | None = None  # the near-goal template's growth as step 0 decided it
        self.near_goal_off = self.resolved.near_goal_off  # why there is none, where NEAR_GOAL_AUTO did not apply
        # what a law's failure may raise and the run records as a fault: the built-ins raise HvsError (PBVS on a
        # degenerate quad); an outside method anything
        self._law_errors = Exception if self.law is not None or self.policy is not None else HvsError
        self.scene = Scene(scenario)
        self.renderer = Renderer(self.scene)
        self.arm = ArmDriver(self.scene)
        # desired flag corners: the target seen from the reference pose (centred, at the standoff)
        ref_pos, ref_R = self.scene.reference_pose()
        self.flag_desired = self.renderer.project(CameraPose(ref_R, ref_pos), self.scene.target_corners_world())
        self.desired_depth = float(scenario.standoff)
        check_start_in_view(self.scene, self.renderer)
        self.ibvs_config = dataclasses.replace(config.ibvs, damping=self.resolved.damping)
        # the camera's frames are rendered only when something reads them: a tracker, a law on the images (or an
        # outside one), a policy, or the records (the recording, the figures); the oracle's features and the
        # evaluation come from geometry and segmentation, so a ground-truth run renders no frame at all
        self.renders_frames = bool(self.tracker is not None or self.policy is not None or self.law is not None
                                   or self.image_law or config.keep_frames)

    def near_goal_plan(self, switched_at: int | None) -> dict | None:
        """run.json's near_goal: the grown template as this run had it (None: LoopConfig.near_goal_inset_px=None)."""
        c = self.config
        if c.near_goal_inset_px is None:
            return None
        on = self.near_goal_off is None
        return {"inset_px": self.near_goal_growth, "auto": c.near_goal_inset_px == NEAR_GOAL_AUTO,
                "within_px": c.near_goal_within_px if on else None,
                "scale": (self.resolved.near_goal_scale or working_scale(self.tracker)) if on else None,
                "off": self.near_goal_off, "switched_at_step": switched_at,
                "note": "the step from which the grown template's corners were the features (null: never switched); "
                        "off: why the run kept one template"}

    # the resolved settings under the names the rest of the package reads
    warp = property(lambda self: self.resolved.warp)
    dofs = property(lambda self: self.resolved.dofs)
    filter_alpha = property(lambda self: self.resolved.filter_alpha)
    template_from = property(lambda self: self.resolved.template_from)
    goal_frames = property(lambda self: self.resolved.goal_frames)

    def controlled_pose_error(self, pose_error: np.ndarray) -> tuple[float, float]:
        """(mm, deg) of the pose error in the DOFs this loop controls."""
        cols = [DOF_NAMES.index(d) for d in self.dofs]
        lin, ang = [c for c in cols if c < 3], [c for c in cols if c >= 3]
        return float(np.linalg.norm(pose_error[lin])), float(np.linalg.norm(pose_error[ang]))

    def true_depths(self) -> np.ndarray:
        """Depth (m) of each target corner in the camera frame, from the simulator (IBVSConfig.depth="true")."""
        return self.renderer.camera_pose().to_camera(self.scene.target_corners_world())[:, 2]

    def _pinhole(self, pts: np.ndarray) -> np.ndarray:
        """Image points with the lens distortion taken out, as a calibrated camera would give IBVS its features
        (the interaction matrix holds for a pinhole); unchanged for a camera without distortion."""
        dist = self.renderer.sensor.distortion
        return undistort_points(self.renderer.K, dist, pts) if dist else pts

    def _distort(self, pts: np.ndarray) -> np.ndarray:
        """Inverse of `_pinhole`: pinhole points back into the camera's image."""
        dist = self.renderer.sensor.distortion
        return distort_points(self.renderer.K, dist, pts) if dist else pts

    def default_inset(self, roi) -> int:
        return default_inset(roi, self.template_from, self.oracle)

    def goal_image(self) -> tuple[np.ndarray, np.ndarray]:
        """The goal image and the target's corners in it (servo/teach.py), with this run's goal frames."""
        return goal_image(self.scene, self.goal_frames)

    def _controller(self, desired_px: np.ndarray, goal: np.ndarray | None, roi):
        """The step-0 law on the desired corners (pinhole pixels): a built-in, or the outside law built at init."""
        cfg, K = self.config, self.renderer.K
        if self.law is not None or self.policy is not None:
            return self.law
        if cfg.controller == "dvs":
            from hvs_sim.control.dvs import DVSController

            return DVSController(K, goal, roi, self.desired_depth, self.ibvs_config)
        law = IBVSController if cfg.controller == "ibvs" else PBVSController
        return law(K, desired_px, self.desired_depth, self.ibvs_config, self.dofs)

    def _control_input(self, features_px, desired_px, true_depths, mode, motion, frame, goal, step) -> ControlInput:
        """What every law is given at a step (control/protocol.py); the features and s* in the pinhole image."""
        K = self.renderer.K
        reads_images = self.law is not None or self.image_law  # IBVS and PBVS read no image: no copy for them
        desired_px = self._pinhole(desired_px)
        if self.tracker is None and not self.oracle:  # a law on the images: no features (not the truth's)
            features_px = np.full_like(desired_px, np.nan)
        s = (features_px - K[:2, 2]) / np.diag(K)[:2]
        s_star = (desired_px - K[:2, 2]) / np.diag(K)[:2]
        depths = true_depths if true_depths is not None else scale_depths(s, s_star, self.desired_depth)
        return ControlInput(features=frozen(s), desired=frozen(s_star), depths=frozen(depths),
                            desired_depth=self.desired_depth, K=frozen(K), features_px=frozen(features_px),
                            desired_px=frozen(desired_px), mode=mode, camera_motion=frozen(motion),
                            dt=1.0 / self.scenario.fps, image=frozen(frame) if reads_images else None,
                            goal_image=frozen(goal) if reads_images else None, step=step)

    def _policy_input(self, frame, gt, goal, desired_px, step) -> PolicyInput:
        return PolicyInput(image=frozen(frame), joints=frozen(gt.joint_positions), goal_image=frozen(goal),
                           K=frozen(self.renderer.K), desired_px=frozen(self._pinhole(desired_px)),
                           dt=1.0 / self.scenario.fps, step=step)

    def _bounded(self, twist: np.ndarray, dofs: tuple[str, ...]) -> ControlOutput:
        """An outside law's or policy's twist in the DOFs it commands, under the loop's per-axis bounds (reported
        as saturated when they cut it, as for the built-in laws)."""
        cols = [DOF_NAMES.index(d) for d in dofs]
        out = np.zeros(6)
        out[cols] = np.asarray(twist, float)[cols]
        out, saturated = bound_twist(out, self.ibvs_config.max_linear, self.ibvs_config.max_angular)
        return ControlOutput(out, np.zeros(0), 0.0, 0.0, saturated, np.zeros(0), tuple(dofs))  # no gain of ours

    def __iter__(self) -> Iterator[StepRecord]:
        return self.run()

    def run(self) -> Iterator[StepRecord]:
        """The episode's steps. With `LoopConfig.pipeline` the tracker works on frame k in a second thread while
        this one steps the physics and renders frame k + 1: frame k's command then acts from step k + 1 (one frame
        of actuation latency, as a real camera's read-out and processing add), and the step takes about the longer
        of the two, not their sum."""
        if not self.config.pipeline:
            yield from self._sequential()
            return
        pool = ThreadPoolExecutor(1, thread_name_prefix="hvs_sim-track")
        threads = torch.get_num_threads()
        try:  # a core left to the renderer (torch's setting is process-wide, restored below)
            torch.set_num_threads(max(1, threads - 1))
            yield from self._pipelined(pool)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            torch.set_num_threads(threads)

    def _sequential(self) -> Iterator[StepRecord]:
        """Capture, track, control, physics one after another: a frame's command acts at once. wall_ms runs from the
        end of the step before, so what the consumer does with a record (the recording, the CSV) counts in the next."""
        wall = Stopwatch()
        cap = self._capture()
        ep = self._step_zero(cap)
        for step in range(self.config.steps):
            timings = dict(cap.timings)
            watch = Stopwatch()
            if ep.grow_from is not None:
                self._switch_to_near_goal(ep, step)
            truth = self.renderer.transfer(ep.flag0, cap.gt.corners, ep.roi0)  # where the features truly are
            first = self._start_tracker(ep, truth) if step == 0 else None
            seen = self._track_step(truth, cap.frame, first)
            timings["track"] = watch.ms()
            with lap(timings, "control"):
                seen, ctrl, cmd = self._control(ep, cap, seen, step)
                self._near_goal_due(ep, seen)
            timings["control"] += cap.depths_ms
            with lap(timings, "physics"):
                self.scene.advance(cmd.qdot)
            yield self._record(step, cap, ep, seen, ctrl, cmd, timings, wall_ms=wall.lap())
            if ep.aborted is not None:
                return
            if step + 1 < self.config.steps:
                cap = self._capture()

    def _pipelined(self, pool: ThreadPoolExecutor) -> Iterator[StepRecord]:
        """Frame k tracked in `pool` while this thread steps the physics with frame k − 1's command and captures frame
        k + 1. A step's render, ground_truth and physics (and the true depths in control) are therefore those of the
        next frame (0 after the last), its track the init's time here plus the tracker's own (Track.ms), and wall_ms
        runs from the end of the step before, so the consumer's time counts in the next step."""
        qdot_due = np.zeros(len(self.arm.limits.qdot_max))  # the command that acts this step: the step before's
        wall = Stopwatch()
        cap = self._capture()
        ep = self._step_zero(cap)
        for step in range(self.config.steps):
            watch = Stopwatch()
            if ep.grow_from is not None:  # no track is in flight between steps
                self._switch_to_near_goal(ep, step)
            truth = self.renderer.transfer(ep.flag0, cap.gt.corners, ep.roi0)
            first = self._start_tracker(ep, truth) if step == 0 else None
            pending = pool.submit(self._track, cap.frame, first) if self.tracker is not None else None
            init_ms = watch.ms()
            timings = {"render": 0.0, "ground_truth": 0.0, "physics": 0.0}  # the last step captures no next frame
            nxt, depths_ms = None, 0.0
            if step + 1 < self.config.steps:  # meanwhile: physics with the command due, then the next frame
                with lap(timings, "physics"):
                    self.scene.advance(qdot_due)
                nxt = self._capture()
                timings.update(nxt.timings)
                depths_ms = nxt.depths_ms
            seen = self._track_step(truth, pending=pending)
            timings["track"] = init_ms + (seen.track.ms if seen.track is not None else 0.0)
            with lap(timings, "control"):
                seen, ctrl, cmd = self._control(ep, cap, seen, step)  # at the next step's arm configuration
                self._near_goal_due(ep, seen)
            timings["control"] += depths_ms
            yield self._record(step, cap, ep, seen, ctrl, cmd, timings, wall_ms=wall.lap())
            if ep.aborted is not None:
                return
            qdot_due, cap = cmd.qdot, nxt

    def _capture(self) -> Capture:
        """Everything a step reads from the scene at its state: the frame and the truth that grades it."""
        r, scene, timings = self.renderer, self.scene, {}
        with lap(timings, "render"):
            frame = r.rgb() if self.renders_frames else None
        with lap(timings, "ground_truth"):
            gt = r.ground_truth(occlusion=self.config.evaluate, counts=False)
        watch = Stopwatch()
        depths = self.true_depths() if self.ibvs_config.depth == "true" else None  # only when asked
        depths_ms = watch.ms()
        return Capture(frame, gt, scene.time, scene.pose_error(), scene.people_poses(), scene.arm_poses(), depths,
                       timings, depths_ms)

    def _step_zero(self, cap: Capture) -> Episode:
        """What the episode keeps from its first frame: the template's image and box, s*, the law, the policy's reset
        and the feature filter (the tracker starts in _start_tracker, whose time counts as tracking)."""
        r, res = self.renderer, self.resolved
        # the template's image and the target's corners in it: this first frame, or the goal image
        template_frame, flag0 = (cap.frame, cap.gt.corners) if res.template_from == "start" else self.goal_image()
        goal = None if res.template_from == "start" else template_frame
        outline = roi_from_corners(flag0)
        inset = self.default_inset(outline) if res.roi_inset_px is None else res.roi_inset_px
        roi = self._template_box(outline, inset, "roi_inset_px")
        roi0 = roi_corners(roi)
        desired = r.transfer(flag0, self.flag_desired, roi0)
        controller = self._controller(self._pinhole(desired), goal, roi)
        near_goal, growth = None, res.near_goal
        if growth == NEAR_GOAL_AUTO:
            growth, self.near_goal_off = near_goal_growth(outline, self.scenario.camera)
        self.near_goal_growth = growth
        if growth is not None:  # the grown box checked now: a run that cannot switch says so
            grown = self._template_box(outline, growth, "near_goal_inset_px")
            near_goal = Template(grown, roi_corners(grown), growth,
                                 r.transfer(flag0, self.flag_desired, roi_corners(grown)))
        if self.policy is not None:
            try:
                self.policy.reset(self._policy_input(cap.frame, cap.gt, goal, desired, 0))
            except Exception as exc:  # outside code: the run cannot start, and says why
                raise StateError(f"policy {self.config.policy!r} failed in reset(): {type(exc).__name__}: {exc}") \
                    from exc
        feature_filter = self._feature_filter(desired) if res.filter_alpha > 0 else None
        ep = Episode(flag0, roi, roi0, inset, desired, template_frame, goal, controller, feature_filter, near_goal)
        self._start_safety(ep, cap)
        return ep

    def _start_safety(self, ep: Episode, cap: Capture) -> None:
        """The safety rule's state for the episode: the gate on s*, the envelope from the camera's start pose (forward
        kinematics) and the taught goal, and the carrier that predicts each measurement from the camera's motion."""
        cam, safety = self.scenario.camera, self.config.safety
        ep.gate = SafetyGate(safety, self.scenario.fps, ep.desired, cam.width, cam.height)
        goal_pos, goal_R = self.scene.reference_pose()
        ep.envelope = Envelope(safety, cap.gt.camera.t, cap.gt.camera.R, goal_pos, goal_R)
        ep.carrier = self._carrier(ep.desired) if self.tracker is not None else None

    def _carrier(self, desired: np.ndarray) -> FeatureFilter:
        """The safety gate's carrier: a feature filter that keeps each measurement whole (α = 1), for its prediction of
        where the camera's own motion takes the last one."""
        return FeatureFilter(self.renderer.K, 1.0, self._pinhole(desired), self.desired_depth)

    def _template_box(self, outline, inset: int, option: str) -> tuple[int, int, int, int]:
        """The template's box: the target's outline box inset (grown, when negative); InputError when a grown box runs
        off the goal image."""
        roi = inset_roi(outline, inset)
        cam = self.scenario.camera  # the goal image's size (a run may render no frames)
        if inset < 0 and not box_in_view(roi, cam):
            raise InputError(f"the template grown {-inset} px beyond the target's outline, {roi[2]}×{roi[3]} px at "
                             f"({roi[0]}, {roi[1]}), runs off the {cam.width}×{cam.height} goal image: grow it less (a "
                             f"{option} nearer 0)")
        return roi

    def _near_goal_due(self, ep: Episode, seen: Measured) -> None:
        """After a step's control: when the features (as control used them) are within near_goal_px of s* and the
        grown box, carried by their homography, is in view, the switch to the grown template is due at the next
        step (ep.grow_from: that homography, the tracker's seed)."""
        if (ep.near_goal is None or ep.grown_at is not None or seen.fault is not None or seen.mode != "align"
                or ep.gate.closed_because is not None):
            return
        if float(np.linalg.norm(seen.features - ep.desired, axis=1).mean()) > self.config.near_goal_within_px:
            return
        A = perspective_transform(ep.roi0, seen.features)  # frame from goal image
        grown = apply_warp(A, ep.near_goal.corners)
        if corners_in_view(grown, self.scenario.camera, IN_VIEW_MARGIN_PX):
            ep.grow_from = A

    def _switch_to_near_goal(self, ep: Episode, step: int) -> None:
        """The tracker (or the near-goal one, near_goal_scale) initialised on the grown template and seeded where the
        small one's corners put it; s*, the law and the feature filter start again on the grown box's corners."""
        near, A = ep.near_goal, ep.grow_from
        tracker = self.near_goal_tracker or self.tracker
        try:
            tracker.init(ep.template_frame, near.roi)
            tracker.seed(A)
        except Exception as exc:  # any cause: the tracker has no template left to servo on
            raise StateError(f"tracker {self.tracker_name!r} could not switch to the near-goal template (ROI "
                             f"{near.roi}) at step {step}: {exc}") from exc
        self.tracker = tracker
        ep.roi, ep.roi0, ep.inset, ep.desired = near.roi, near.corners, near.inset, near.desired
        ep.controller = self._controller(self._pinhole(near.desired), ep.goal, near.roi)
        if ep.feature_filter is not None:
            ep.feature_filter = self._feature_filter(near.desired)
        ep.gate.set_desired(near.desired)
        if ep.carrier is not None:  # other corners from here: nothing to carry
            ep.carrier = self._carrier(near.desired)
        ep.grown_at, ep.grow_from = step, None

    def _feature_filter(self, desired: np.ndarray) -> FeatureFilter:
        """A fresh feature filter (LoopConfig.feature_filter, resolved) on s* = `desired`."""
        return FeatureFilter(self.renderer.K, self.resolved.filter_alpha, self._pinhole(desired), self.desired_depth)

    def _start_tracker(self, ep: Episode, truth: np.ndarray) -> Track | None:
        """The tracker's init on the template: its own track of the first frame with a start template; with a goal
        one it is then seeded at the target's corners in the first frame. Without a template there is nothing to
        servo on: a failure ends the run."""
        if self.tracker is None:
            return None
        try:
            first = self.tracker.init(ep.template_frame, ep.roi)
            if self.template_from == "goal":  # the target's corners marked in the first frame
                first = None
                self.tracker.seed(perspective_transform(ep.roi0, truth))
            return first
        except Exception as exc:  # any cause: the run cannot go on, and says why
            where = "the first frame" if self.template_from == "start" else "the goal image and the first frame"
            raise StateError(f"tracker {self.tracker_name!r} could not start on {where} (template ROI {ep.roi}): "
                             f"{exc}") from exc

    def _track(self, frame: np.ndarray, first: Track | None) -> Track:
        """The tracker's corners for a frame (`first`: the init's own track of step 0, when it has one)."""
        track = first if first is not None else self.tracker.update(frame)
        if not np.all(np.isfinite(track.corners)):
            raise FloatingPointError("tracker returned non-finite corners")
        return track

    def _track_step(self, truth: np.ndarray, frame: np.ndarray | None = None, first: Track | None = None,
                    pending: Future | None = None) -> Measured:
        """The step's corners: the tracker's, here or from the tracking thread (`pending`), else the truth's. A
        tracker fault must not crash the run: it is recorded, and control holds the arm."""
        try:
            if self.tracker is None:  # the oracle's features; a law on the images or a policy reads none
                return Measured(None, truth, truth, truth, "align", None)
            track = pending.result() if pending is not None else self._track(frame, first)
            return Measured(track, truth, track.corners, track.corners, track.mode, None)
        except Exception as exc:  # noqa: BLE001 - any tracker fault
            lost = truth * np.nan
            return Measured(None, truth, lost, lost, "fault", f"{type(exc).__name__}: {exc}")

    def _control(self, ep: Episode, cap: Capture, seen: Measured,
                 step: int) -> tuple[Measured, ControlOutput | None, JointCommand]:
        """The law's (or policy's) twist on the step's features, through the feature filter, as joint velocities at
        the arm's configuration now. A fault (the tracker's, or the law's) gives a zero twist: the arm holds."""
        features, mode, fault = seen.features, seen.mode, seen.fault
        ctrl = None
        control_px = self._pinhole(features) if fault is None else features
        camera, prev = cap.gt.camera, ep.camera_prev
        motion = np.eye(4) if prev is None else np.linalg.solve(prev.matrix(), camera.matrix())
        ep.camera_prev = camera
        if ep.feature_filter is not None:  # the camera's pose from the joints' forward kinematics, as ArmDriver reads it
            control_px = ep.feature_filter.update(control_px, camera, usable=fault is None and mode != "lost")
            if fault is None:
                features = self._distort(control_px)
        if fault is None:
            # PBVS cannot take a pose from a degenerate quad, an outside law or policy may fail or answer garbage:
            # like a tracker fault, stop the arm and record it
            try:
                if self.policy is not None:
                    ctrl = self._bounded(self.policy.act(self._policy_input(cap.frame, cap.gt, ep.goal, ep.desired,
                                                                            step)), self.dofs)
                else:
                    inp = self._control_input(control_px, ep.desired, cap.depths, mode, motion, cap.frame, ep.goal, step)
                    ctrl = ep.controller.compute(inp)
                    if self.law is not None:  # (twist, dofs): bounded as the built-in laws bound theirs
                        ctrl = self._bounded(ctrl[0], ctrl[1] or self.dofs)
            except self._law_errors as exc:
                fault, mode = f"{type(exc).__name__}: {exc}", "fault"
                if ep.feature_filter is not None:  # a faulty frame clears the filter, as a tracker fault does
                    ep.feature_filter.reset()
        twist = self._safe_twist(ep, cap, seen, ctrl, fault)
        if ctrl is not None:
            ctrl = dataclasses.replace(ctrl, twist=twist)
        cmd = self.arm.command(twist)
        return dataclasses.replace(seen, features=features, mode=mode, fault=fault), ctrl, cmd

    def _safe_twist(self, ep: Episode, cap: Capture, seen: Measured, ctrl: ControlOutput | None,
                    fault: str | None) -> np.ndarray:
        """The law's twist through the safety rule (control/safety.py): the gate judges the tracker's own corners
        (not the filtered ones) and holds the arm while it does not see; a twist that would carry the camera out of
        the envelope within one step is not commanded, and the episode ends (ep.aborted)."""
        jump, px = None, None
        if self.tracker is not None and seen.fault is None:
            px = seen.tracked
            pinhole = self._pinhole(px)
            carried = ep.carrier.predict(cap.gt.camera) if ep.carrier.state is not None else None
            jump = None if carried is None else float(np.linalg.norm(pinhole - carried, axis=1).max())
            ep.carrier.update(pinhole, cap.gt.camera, usable=seen.mode != "lost")
        confidence = seen.track.confidence if seen.track is not None else None
        ep.held_because = ep.gate.update(px, seen.mode, confidence, fault is not None, jump)
        twist = ep.gate.twist(ctrl.twist if ctrl is not None else None)
        if not np.any(twist):
            return twist
        ep.aborted = ep.envelope.check(cap.gt.camera.t, cap.gt.camera.R, twist, 1.0 / self.scenario.fps)
        if ep.aborted is not None:
            return np.zeros(6)
        return twist

    def _record(self, step: int, cap: Capture, ep: Episode, seen: Measured, ctrl: ControlOutput | None,
                cmd: JointCommand, timings: dict[str, float], wall_ms: float | None = None) -> StepRecord:
        """The step as logged and graded: what the loop did, beside the truth it did not see."""
        gt, truth, res = cap.gt, seen.truth, self.resolved
        twist, gain, sat, sv = ((ctrl.twist, ctrl.gain, ctrl.saturated, ctrl.singular_values) if ctrl is not None
                                else (np.zeros(6), 0.0, False, np.zeros(0)))
        graded = seen.fault is None and (self.tracker is not None or self.oracle)
        return StepRecord(
            step=step, time=cap.time, frame=cap.frame if self.config.keep_frames else None, track=seen.track,
            mode=seen.mode, features=seen.features, gt_features=truth, desired=ep.desired,
            error_px=float(np.linalg.norm(truth - ep.desired, axis=1).mean()),
            tracker_error_px=float(np.linalg.norm(seen.tracked - truth, axis=1).mean()) if graded else float("nan"),
            occlusion=gt.occlusion, twist=twist, qdot=cmd.qdot, q=gt.joint_positions, camera=gt.camera, gain=gain,
            saturated=sat or cmd.velocity_saturated, limit_blocked=cmd.limit_blocked, fault=seen.fault,
            timings=timings, pose_error=cap.pose_error, singular_values=sv,
            dofs=(ctrl.dofs or res.dofs) if ctrl is not None else res.dofs, damping=self.ibvs_config.damping,
            feature_filter=res.filter_alpha,
            filter_restarted=ep.feature_filter is not None and ep.feature_filter.restarted,
            template=(res.template_from, int(ep.inset), res.goal_frames),
            target_in_view=corners_in_view(gt.corners, self.scenario.camera),
            controlled_pose_error=self.controlled_pose_error(cap.pose_error), people=cap.people, arm=cap.arm,
            wall_ms=wall_ms, held_because=ep.held_because, aborted=ep.aborted)
