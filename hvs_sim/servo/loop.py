"""The closed loop's agent: tracker, feature filter, law and safety rule stepping a ServoTask (servo/task.py: the
world) over one episode, one record per step (servo/records.py; logging and plots only read them). The step and its
drivers are servo/step.py, the template schedule servo/templates.py, the law and what it uses servo/laws.py. A
tracker's or law's fault stops the arm for that step and is recorded; the loop goes on.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch

from hvs_sim import plugins
from hvs_sim.control.arm import JointCommand
from hvs_sim.control.feature_filter import FeatureFilter
from hvs_sim.control.features import scale_depths
from hvs_sim.control.laws.ibvs import DOF_NAMES, ControlOutput
from hvs_sim.control.protocol import ControlInput, PolicyInput
from hvs_sim.control.safety import Envelope, SafetyGate
from hvs_sim.errors import ConfigError, HvsError, StateError
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.sensor import distort_points, undistort_points
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.laws import bounded
from hvs_sim.servo.parts import Capture, Episode, Measured, frozen
from hvs_sim.servo.plan import build_method
from hvs_sim.servo.records import StepRecord
from hvs_sim.servo.step import pipelined, sequential
from hvs_sim.servo.task import Observation, ServoTask
from hvs_sim.servo.templates import TemplateSchedule
from hvs_sim.tracking import Track
from hvs_sim.tracking.warp import perspective_transform


class ServoLoop:
    """One closed-loop episode of a scenario with the arm mount and a named tracker."""

    def __init__(self, scenario: Scenario, tracker: str = "deep_lk", config: LoopConfig | None = None, **tracker_config):
        config = LoopConfig() if config is None else config
        if scenario.mount != "arm":
            raise ConfigError(f"the closed loop needs mount='arm', got {scenario.mount!r}")
        # tracker, law or policy and the plan, built before the scene (servo/plan.py)
        method = build_method(tracker, config, tracker_config)
        self.law, self.policy, self.servo_law = method.law, method.policy, method.servo_law
        self.tracker, self.resolved = method.tracker, method.resolved
        self.image_law = not self.servo_law.caps.features
        self.scenario, self.tracker_name, self.config = scenario, tracker, config
        self.oracle = tracker == plugins.GROUND_TRUTH
        near_goal_tracker = None  # the tracker on the near-goal template, when it is another (near_goal_scale)
        if self.resolved.near_goal_scale is not None and self.tracker is not None:
            near_goal_tracker = self.tracker.with_scale(self.resolved.near_goal_scale)
        # what a law's failure may raise and the run records as a fault: the built-ins raise HvsError (PBVS on a
        # degenerate quad); an outside method anything
        self._law_errors = Exception if self.servo_law.caps.outside or self.policy is not None else HvsError
        self.task = ServoTask(scenario)  # the world this agent steps: scene, renderer, arm, s*, metrics
        self.task.reset()  # ConfigError when the target is not fully in view from the start
        world = self.task.world
        self.scene, self.renderer, self.arm = world.scene, world.renderer, world.arm
        self.flag_desired = world.desired  # the target's corners seen from the reference pose
        self.desired_depth = float(scenario.standoff)
        self.templates = TemplateSchedule(self.scene, self.renderer, config, self.resolved, tracker, self.tracker,
                                          near_goal_tracker, self.flag_desired)
        self.ibvs_config = dataclasses.replace(config.ibvs, damping=self.resolved.damping)
        # the camera's frames are rendered only when something reads them: a tracker, a law on the images (or an
        # outside one), a policy, or the records (the recording, the figures); the oracle's features and the
        # evaluation come from geometry and segmentation, so a ground-truth run renders no frame at all
        self.renders_frames = bool(self.tracker is not None or self.policy is not None or self.servo_law.caps.images
                                   or config.keep_frames)

    def near_goal_plan(self, switched_at: int | None) -> dict | None:
        """run.json's near_goal: the grown template as this run had it (TemplateSchedule.plan)."""
        return self.templates.plan(switched_at)

    # the resolved settings under the names the rest of the package reads
    warp = property(lambda self: self.resolved.warp)
    dofs = property(lambda self: self.resolved.dofs)
    filter_alpha = property(lambda self: self.resolved.filter_alpha)
    template_from = property(lambda self: self.resolved.template_from)
    goal_frames = property(lambda self: self.resolved.goal_frames)
    near_goal_off = property(lambda self: self.templates.near_goal_off)  # why no near-goal template (None: there is)
    near_goal_tracker = property(lambda self: self.templates.near_goal_tracker)

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
        return self.templates.default_inset(roi)

    def goal_image(self) -> tuple[np.ndarray, np.ndarray]:
        """The goal image and the target's corners in it (servo/teach.py), with this run's goal frames."""
        return self.templates.goal_image()

    def _controller(self, desired_px: np.ndarray, goal: np.ndarray | None, roi):
        """The law on the desired corners (pinhole pixels) or the goal image's region (None: a policy's episode)."""
        if self.policy is not None:
            return None
        return self.servo_law.build(self.renderer.K, desired_px, self.desired_depth, self.ibvs_config, self.dofs, goal,
                                    roi)

    def _control_input(self, features_px, desired_px, true_depths, mode, motion, frame, goal, step) -> ControlInput:
        """What every law is given at a step (control/protocol.py); the features and s* in the pinhole image."""
        K = self.renderer.K
        reads_images = self.servo_law.caps.images  # IBVS and PBVS read no image: no copy for them
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

    def _policy_input(self, obs: Observation, goal, desired_px, step) -> PolicyInput:
        return PolicyInput(image=frozen(obs.frame), joints=frozen(obs.joints), goal_image=frozen(goal),
                           K=frozen(self.renderer.K), desired_px=frozen(self._pinhole(desired_px)),
                           dt=1.0 / self.scenario.fps, step=step)

    def __iter__(self) -> Iterator[StepRecord]:
        return self.run()

    def run(self) -> Iterator[StepRecord]:
        """The episode's steps. With `LoopConfig.pipeline` the tracker works on frame k in a second thread while
        this one steps the physics and renders frame k + 1: frame k's command then acts from step k + 1 (one frame
        of actuation latency, as a real camera's read-out and processing add), and the step takes about the longer
        of the two, not their sum."""
        if not self.config.pipeline:
            yield from sequential(self)
            return
        pool = ThreadPoolExecutor(1, thread_name_prefix="hvs_sim-track")
        threads = torch.get_num_threads()
        try:  # a core left to the renderer (torch's setting is process-wide, restored below)
            torch.set_num_threads(max(1, threads - 1))
            yield from pipelined(self, pool)
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            torch.set_num_threads(threads)

    def step_zero(self, cap: Capture) -> Episode:
        """What the episode keeps from its first frame: the templates (TemplateSchedule.start), s*, the law, the
        policy's reset and the feature filter (the tracker starts in start_tracker, whose time counts as tracking)."""
        template_frame, goal, t, flag0, near_goal = self.templates.start(cap)
        controller = self._controller(self._pinhole(t.desired), goal, t.roi)
        if self.policy is not None:
            try:
                self.policy.reset(self._policy_input(cap.obs, goal, t.desired, 0))
            except Exception as exc:  # outside code: the run cannot start, and says why
                raise StateError(f"policy {self.config.policy!r} failed in reset(): {type(exc).__name__}: {exc}") \
                    from exc
        feature_filter = self._feature_filter(t.desired) if self.resolved.filter_alpha > 0 else None
        # the safety rule's state: the gate on s*, the envelope from the camera's start pose (forward kinematics) and
        # the taught goal, and the carrier that predicts each measurement from the camera's motion
        cam, safety = self.scenario.camera, self.config.safety
        goal_pos, goal_R = self.scene.reference_pose()
        return Episode(flag0, t.roi, t.corners, t.inset, t.desired, template_frame, goal, controller, feature_filter,
                       gate=SafetyGate(safety, self.scenario.fps, t.desired, cam.width, cam.height),
                       envelope=Envelope(safety, cap.obs.camera.t, cap.obs.camera.R, goal_pos, goal_R),
                       carrier=self._carrier(t.desired) if self.tracker is not None else None, near_goal=near_goal)

    def _carrier(self, desired: np.ndarray) -> FeatureFilter:
        """The safety gate's carrier: a feature filter that keeps each measurement whole (α = 1), for its prediction of
        where the camera's own motion takes the last one."""
        return FeatureFilter(self.renderer.K, 1.0, self._pinhole(desired), self.desired_depth)

    def switch_to_near_goal(self, ep: Episode, step: int) -> None:
        """The tracker on the grown template (TemplateSchedule.switch); s*, the law and the feature filter start again
        on the grown box's corners."""
        self.tracker = self.templates.switch(ep, self.tracker, step)
        ep.controller = self._controller(self._pinhole(ep.desired), ep.goal, ep.roi)
        if ep.feature_filter is not None:
            ep.feature_filter = self._feature_filter(ep.desired)
        ep.gate.set_desired(ep.desired)
        if ep.carrier is not None:  # other corners from here: nothing to carry
            ep.carrier = self._carrier(ep.desired)

    def _feature_filter(self, desired: np.ndarray) -> FeatureFilter:
        """A fresh feature filter (LoopConfig.feature_filter, resolved) on s* = `desired`."""
        return FeatureFilter(self.renderer.K, self.resolved.filter_alpha, self._pinhole(desired), self.desired_depth)

    def start_tracker(self, ep: Episode, truth: np.ndarray) -> Track | None:
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

    def control(self, ep: Episode, obs: Observation, depths: np.ndarray | None, seen: Measured,
                step: int) -> tuple[Measured, ControlOutput | None, JointCommand]:
        """The law's (or policy's) twist on the step's features, through the feature filter, as joint velocities at
        the arm's configuration now. A fault (the tracker's, or the law's) gives a zero twist: the arm holds."""
        features, mode, fault = seen.features, seen.mode, seen.fault
        ctrl = None
        control_px = self._pinhole(features) if fault is None else features
        camera, prev = obs.camera, ep.camera_prev
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
                    ctrl = bounded(self.policy.act(self._policy_input(obs, ep.goal, ep.desired, step)), self.dofs,
                                   self.ibvs_config)
                elif ep.controller is not None:  # a policy's episode has no law
                    inp = self._control_input(control_px, ep.desired, depths, mode, motion, obs.frame, ep.goal, step)
                    ctrl = ep.controller.compute(inp)  # one ControlOutput, built-in or outside
            except self._law_errors as exc:
                fault, mode = f"{type(exc).__name__}: {exc}", "fault"
                if ep.feature_filter is not None:  # a faulty frame clears the filter, as a tracker fault does
                    ep.feature_filter.reset()
        twist = self._safe_twist(ep, obs, seen, ctrl, fault)
        if ctrl is not None:
            ctrl = dataclasses.replace(ctrl, twist=twist)
        cmd = self.arm.command(twist)
        return dataclasses.replace(seen, features=features, mode=mode, fault=fault), ctrl, cmd

    def _safe_twist(self, ep: Episode, obs: Observation, seen: Measured, ctrl: ControlOutput | None,
                    fault: str | None) -> np.ndarray:
        """The law's twist through the safety rule (control/safety.py): the gate judges the tracker's own corners
        (not the filtered ones) and holds the arm while it does not see; a twist that would carry the camera out of
        the envelope within one step is not commanded, and the episode ends (ep.aborted)."""
        jump, px = None, None
        if ep.carrier is not None and seen.fault is None:  # a tracker's corners (the carrier is None without one)
            px = seen.tracked
            pinhole = self._pinhole(px)
            carried = ep.carrier.predict(obs.camera) if ep.carrier.state is not None else None
            jump = None if carried is None else float(np.linalg.norm(pinhole - carried, axis=1).max())
            ep.carrier.update(pinhole, obs.camera, usable=seen.mode != "lost")
        confidence = seen.track.confidence if seen.track is not None else None
        ep.held_because = ep.gate.update(px, seen.mode, confidence, fault is not None, jump, obs.camera)
        twist = ep.gate.twist(ctrl.twist if ctrl is not None else None)
        if not np.any(twist):
            return twist
        ep.aborted = ep.envelope.check(obs.camera.t, obs.camera.R, twist, 1.0 / self.scenario.fps)
        if ep.aborted is not None:
            return np.zeros(6)
        return twist
