"""`hvs_sim/VisualServo-v1` (and `-v0`): drive the wrist camera with a bounded twist to centre the target.

Observation (`obs_mode`): "image" {"image": H×W×3 uint8 wrist-camera frame, "joints"}; "image+goal" adds "goal" (the
goal image: the camera at the reference pose, people left out) and "desired" (s*, the target's corners there, 4×2
pixels); "image+goal+depth" adds "depth" (H×W float32 metres along the optical axis); "features" has no image:
"features" (the target's corners now, 4×2 pixels: the truth, or a tracker's with `tracker=`), "desired" and "joints".
"joints": v1 gives (sin q, cos q, q̇) (`joints="sincos"`), which no small motion flips; v0 the angles wrapped to
[−π, π) and q̇ (`joints="wrapped"`), as before.
Action: a camera twist (vx, vy, vz, wx, wy, wz) in [−1, 1]⁶, scaled by max_linear / max_angular,
or with action_type="joint" joint velocities in [−1, 1]ⁿ scaled by the joint velocity limits.
Reward: minus the ground-truth mean corner error to the desired corners, in pixels of the
observation (`reward="pixels"`, the default) or divided by the image diagonal (`reward="normalised"`,
about −0.5 … 0, easier on a value function).
Terminated when that error stays below `converge_px` for `hold_steps` steps.
info: error_px, occlusion (true share of the target hidden), converged and is_success (the same: read by SB3, HER and
gymnasium-robotics), held_steps, K (3×3 intrinsics), camera_pose (4×4, world from camera, OpenCV axes); with a
tracker, tracker_mode and tracker_fault.
render() ("rgb_array": a third-person view; "depth_array": the wrist camera's depth), reset(options=...) ("scenario",
"start_offset", "camera", "people"; other keys refused by name), `appearance`, the defaults (scenario "clear", 160×120,
the ideal camera) and vector envs (workers started with 'spawn' once the parent has rendered): docs/usage.md, "The
gymnasium environment". arm: one of scene.arms.ARMS; the joints' observation and a joint action have its size.
An action must have the space's shape and finite values (a NaN would poison the physics); it is clipped to [−1, 1].

An adapter over hvs_sim.servo.task.ServoTask, which owns the scene, renderer, arm, s* and the metrics (and a reset's
reuse of the compiled model); the env adds the spaces, the start draws, the reward and the convergence rule.
"""

from __future__ import annotations

import dataclasses
import numbers
from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from hvs_sim.errors import ConfigError, InputError, StateError, choice_error
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.task import ServoTask
from hvs_sim.servo.tracked import TrackedCorners
from hvs_sim.validate import check_number

OBS_MODES = ("image", "image+goal", "image+goal+depth", "features")
JOINT_OBS = ("wrapped", "sincos")
RESET_OPTIONS = ("scenario", "start_offset", "camera", "people")
APPEARANCES = ("per_episode", "fixed")
RENDER_MODES = ("rgb_array", "depth_array")
PIXEL_BOUND = 1e4  # corner coordinates in the observation: pixels, far outside any image
START_DRAWS = 20  # start poses drawn per reset before giving up (unreachable, or the target out of view)
MAX_DEPTH_M = 10.0  # the scene's far clip plane (scene/world.py): the depth observation's bound
ACTION_TYPES = ("twist", "joint")
REWARDS = ("pixels", "normalised")
MIN_IMAGE = 64  # pixels, as CameraConfig accepts


class ResetNeededError(StateError, gym.error.ResetNeeded):
    """step() before reset(): an HvsError that gymnasium's wrappers also recognise."""


class VisualServoEnv(gym.Env):
    metadata: ClassVar[dict] = {"render_modes": list(RENDER_MODES), "render_fps": 30}

    def __init__(self, scenario: str = "clear", render_mode: str | None = None, action_type: str = "twist",
                 width: int = 160, height: int = 120, max_offset: float = 0.05, max_roll: float = 0.15,
                 converge_px: float = 1.0, hold_steps: int = 5, max_linear: float = 0.1, max_angular: float = 0.5,
                 camera: str = "ideal", reward: str = "pixels", obs_mode: str = "image", joints: str = "wrapped",
                 tracker: str = "ground_truth", render_size: tuple[int, int] = (480, 360),
                 appearance: str = "per_episode", arm: str = "jaco"):
        """camera: the camera model of the observations (hvs_sim.sensor.SENSOR_PRESETS), e.g.
        "phone_handheld" for exposure changes, blur, noise and JPEG as a real camera gives them.
        tracker: with obs_mode "features", whose corners the observation holds: "ground_truth", a tracker of the
        registry or an outside one (hvs_sim.plugins), initialised on the episode's first frame."""
        if render_mode not in (None, *RENDER_MODES):
            raise choice_error("render_mode", render_mode, [*RENDER_MODES, "None"])
        for name, value, choices in (("obs_mode", obs_mode, OBS_MODES), ("appearance", appearance, APPEARANCES),
                                     ("joints", joints, JOINT_OBS)):
            if value not in choices:
                raise choice_error(name, value, choices)
        if tracker != "ground_truth":
            if obs_mode != "features":
                raise ConfigError(f"tracker={tracker!r} fills the 'features' observation: give obs_mode='features'")
            from hvs_sim.plugins import check_any_tracker

            check_any_tracker(tracker)
        for name, v in zip(("render width", "render height"), render_size, strict=True):
            check_number(name, v, 64, 4096, integer=True)
        for name, value, choices in (("action_type", action_type, ACTION_TYPES), ("reward", reward, REWARDS)):
            if value not in choices:
                raise choice_error(name, value, choices)
        check_number("width", width, MIN_IMAGE, integer=True)
        check_number("height", height, MIN_IMAGE, integer=True)
        check_number("max_offset (m)", max_offset, 0, 0.2)
        check_number("max_roll (rad)", max_roll, 0, 1.0)
        check_number("converge_px", converge_px, 0, lo_open=True)
        check_number("hold_steps", hold_steps, 1, integer=True)
        check_number("max_linear (m/s)", max_linear, 0, lo_open=True)
        check_number("max_angular (rad/s)", max_angular, 0, lo_open=True)
        self.reward_scale = 1.0 / float(np.hypot(width, height)) if reward == "normalised" else 1.0
        self.render_mode, self.action_type = render_mode, action_type
        self.obs_mode, self.joint_obs, self.tracker_name = obs_mode, joints, tracker
        self.render_size, self.scenario_name = tuple(render_size), scenario
        self.base = make_scenario(scenario, mount="arm", camera=CameraConfig(width=width, height=height, sensor=camera),
                                  arm=arm)
        self.tracker, self.max_offset, self.max_roll = None, max_offset, max_roll  # tracker: TrackedCorners at reset
        self.converge_px, self.hold_steps = converge_px, hold_steps
        self.scale = np.array([max_linear] * 3 + [max_angular] * 3)
        self.appearance, self._look_seed = appearance, None
        self.task = ServoTask(self.base, framebuffer=self.render_size if render_mode == "rgb_array" else None)
        from hvs_sim.scene.arms import ARMS, robosuite_robots

        if ARMS[arm].from_files:  # the model files are there, or the env says how to get them (not 20 failed draws)
            robosuite_robots()
        n = ARMS[arm].dof  # joints in the observation and in a joint action
        # velocities well inside ±10 rad/s (actuators stop at < 1 rad/s)
        if joints == "wrapped":  # angles wrapped to [−π, π)
            lo, hi = np.r_[[-np.pi] * n, [-10.0] * n], np.r_[[np.pi] * n, [10.0] * n]
        else:  # sin q, cos q, q̇
            lo, hi = np.r_[[-1.0] * 2 * n, [-10.0] * n], np.r_[[1.0] * 2 * n, [10.0] * n]
        image = spaces.Box(0, 255, (height, width, 3), np.uint8)
        corners = spaces.Box(-PIXEL_BOUND, PIXEL_BOUND, (4, 2), np.float64)
        obs = {"joints": spaces.Box(lo, hi, lo.shape, np.float64)}
        if obs_mode == "features":
            obs.update(features=corners, desired=corners)
        else:
            obs["image"] = image
        if obs_mode.startswith("image+goal"):
            obs.update(goal=image, desired=corners)
        if obs_mode == "image+goal+depth":
            obs["depth"] = spaces.Box(0.0, MAX_DEPTH_M, (height, width), np.float32)
        self.observation_space = spaces.Dict(obs)
        self.action_space = spaces.Box(-1.0, 1.0, (6 if action_type == "twist" else n,), np.float32)

    # the task's world under the names the env's users read
    scene = property(lambda self: self.task.scene)
    renderer = property(lambda self: self.task.renderer)
    desired = property(lambda self: self.task.desired)  # s*: the target's corners at the reference pose
    model_builds = property(lambda self: self.task.model_builds)  # scenes built and compiled (the rest restarted one)

    def _obs(self):
        seen = self.task.observe(frame=not (self.obs_mode == "features" and self.tracker is None))
        frame, q, qd = seen.frame, seen.joints, seen.joint_velocities
        angles = [(q + np.pi) % (2 * np.pi) - np.pi] if self.joint_obs == "wrapped" else [np.sin(q), np.cos(q)]
        obs = {"joints": np.concatenate([*angles, qd])}
        if self.obs_mode == "features":  # with a tracker, its box's corners and where they go at the goal
            if self.tracker is None:  # the truth
                obs.update(features=self.task.truth(occlusion=False).corners.astype(np.float64), desired=self.desired.copy())
            else:
                obs.update(features=self.tracker.update(frame), desired=self.tracker.desired.copy())
        else:
            obs["image"] = frame
        if self.obs_mode.startswith("image+goal"):
            obs.update(goal=self.goal.copy(), desired=self.desired.copy())
        if self.obs_mode == "image+goal+depth":
            obs["depth"] = np.clip(self.renderer.depth(), 0.0, MAX_DEPTH_M).astype(np.float32)
        return obs

    def _info(self, err: float, converged: bool) -> dict:
        info = {"error_px": err, "occlusion": self._occlusion, "converged": converged, "is_success": converged,
                "held_steps": self._held, "K": self.renderer.K.copy(), "camera_pose": self.renderer.camera_pose().matrix()}
        if self.tracker is not None:
            info.update(tracker_mode=self.tracker.mode, tracker_fault=self.tracker.fault)
        return info

    def _grade(self, truth) -> float:
        """The step's error to s* (px), keeping its occlusion for info."""
        self._occlusion = float(truth.occlusion)
        return self.task.error_px(truth)

    def _episode_scenario(self, options) -> object:
        """The base scenario with this episode's options (validated; unknown keys refused by name)."""
        if options is None:
            return self.base
        if not isinstance(options, dict):
            raise InputError(f"reset options must be a dict with keys among {', '.join(RESET_OPTIONS)}, got "
                             f"{type(options).__name__}")
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise InputError(f"unknown reset option(s) {', '.join(map(str, unknown))}; accepted: {', '.join(RESET_OPTIONS)}")
        cam = self.base.camera
        try:
            return make_scenario(options.get("scenario", self.scenario_name), mount="arm", arm=self.base.arm,
                                 camera=CameraConfig(width=cam.width, height=cam.height,
                                                     sensor=options.get("camera", cam.sensor)),
                                 **({"people": options["people"]} if "people" in options else {}))
        except ConfigError as exc:
            raise InputError(f"reset options: {exc}") from None

    def reset(self, *, seed=None, options=None):
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0):
            raise InputError(f"seed must be None or a non-negative integer, got {seed!r}")
        super().reset(seed=None if seed is None else int(seed))
        if seed is not None:  # a seeded reset draws its look again, so that it repeats from any earlier state
            self._look_seed = None

        base = self._episode_scenario(options)
        rng = self.np_random
        given = options is not None and "start_offset" in options
        for draw in range(1 if given else START_DRAWS):
            offset = (*rng.uniform(-self.max_offset, self.max_offset, 3), rng.uniform(-self.max_roll, self.max_roll))
            if given:
                offset = options["start_offset"]
            look = noise = int(rng.integers(0, 2**31 - 1))  # the episode's look and its camera noise
            if self.appearance == "fixed":
                look = self._look_seed = look if self._look_seed is None else self._look_seed
            try:
                scen = dataclasses.replace(base, seed=look, start_offset=tuple(float(v) for v in offset))
            except (TypeError, ValueError, ConfigError) as exc:
                raise InputError(f"reset option start_offset {offset!r}: {exc}; accepted: 4 or 6 finite numbers (dx, "
                                 "dy, dz m, roll[, pitch, yaw] rad)") from None
            try:  # a start the arm cannot reach or with the target out of view: a drawn one is drawn again
                self.task.reset(scenario=scen, noise_seed=noise)  # no scene until a start pose is usable
                break
            except ConfigError as exc:
                if given or draw == START_DRAWS - 1:
                    raise InputError(f"no usable start pose ({exc})") from None
        if self.obs_mode.startswith("image+goal"):
            self.goal = self.task.goal_image()[0]  # one frame of the clear scene at the reference pose
        self._held = 0
        self.tracker = None if self.tracker_name == "ground_truth" else TrackedCorners(self.tracker_name, self.task)
        err = self._grade(self.task.truth(occlusion=True, counts=True))
        return self._obs(), self._info(err, False)

    def step(self, action):
        if self.scene is None:
            raise ResetNeededError("call reset() before step()")
        try:
            raw = np.asarray(action)
        except (TypeError, ValueError):
            raw = np.asarray(None)
        if raw.dtype.kind not in "iuf":  # strings, complex numbers, objects, bools are not velocities
            raise InputError(f"action must be real numbers of shape {self.action_space.shape}, got {action!r}")
        a = raw.astype(np.float64)
        if a.shape != self.action_space.shape:
            raise InputError(f"action must have shape {self.action_space.shape} ({self.action_type}), got {a.shape}")
        if not np.isfinite(a).all():
            raise InputError("action contains NaN or inf; the physics would be left in an invalid state")
        a = np.clip(a, -1.0, 1.0)
        act = {"twist": a * self.scale} if self.action_type == "twist" else {"qdot": a * self.task.arm.limits.qdot_max}
        err = self._grade(self.task.step(**act, frame=False, counts=True)[1])  # the frame: _obs's, when it needs one
        self._held = self._held + 1 if err < self.converge_px else 0
        terminated = self._held >= self.hold_steps
        obs = self._obs()
        return obs, -err * self.reward_scale, terminated, False, self._info(err, terminated)

    def render(self):
        if self.scene is None:
            raise ResetNeededError("call reset() before render()")
        if self.render_mode == "rgb_array":
            return self.renderer.scene_view(*self.render_size)
        if self.render_mode == "depth_array":
            return self.renderer.depth()
        return None

    def close(self):
        self.task.close()
