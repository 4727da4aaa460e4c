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
render(): "rgb_array" a third-person view of the scene (arm, wall, people; `render_size`), "depth_array" the wrist
camera's depth.
reset(options=...): any of "scenario", "start_offset" ((dx, dy, dz, roll) or (dx, dy, dz, roll, pitch, yaw), m and
rad), "camera", "people" for that episode; other keys are refused by name.
Reset cost: an episode whose compiled model would be the same as the last one's (scene.world.model_key: the same
scenario, camera and people, the seed drawing nothing of the model) restarts on it (Scene.restart) instead of building
and compiling the scene and its rendering context again. With people or per-seed textures each episode's seed draws a
new look, hence a new model; `appearance="fixed"` keeps the look drawn at the first reset (or the last reset with a
seed) so those episodes restart too, at the price of less visual variety (the camera's noise still differs by episode).

arm: one of scene.arms.ARMS ("jaco", 6 joints; "panda", 7; "ur5e", 6; "gen3", 7): the joints' observation and a
joint action have the arm's size.
Defaults worth knowing: scenario "clear" (no person; pass e.g. scenario="walk_by"), a 160×120
image, the ideal camera. An action must have the action space's shape and finite values (a NaN
would poison the physics); values outside [−1, 1] are clipped, as the space says.
Workers of a vector env must be started with 'spawn' once the parent has rendered (see gl.py).
"""

from __future__ import annotations

import dataclasses
import numbers
from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from hvs_sim.control.arm import ArmDriver
from hvs_sim.errors import ConfigError, InputError, StateError, choice_error
from hvs_sim.render.camera import CameraPose
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.validate import check_number

OBS_MODES = ("image", "image+goal", "image+goal+depth", "features")
JOINT_OBS = ("wrapped", "sincos")
RESET_OPTIONS = ("scenario", "start_offset", "camera", "people")
APPEARANCES = ("per_episode", "fixed")
RENDER_MODES = ("rgb_array", "depth_array")
PIXEL_BOUND = 1e4  # corner coordinates in the observation: pixels, far outside any image
START_DRAWS = 20  # start poses drawn per reset before giving up (unreachable, or the target out of view)
MAX_DEPTH_M = 10.0  # the scene's far clip plane (scene/world.py): the depth observation's bound


class ResetNeededError(StateError, gym.error.ResetNeeded):
    """step() before reset(): an HvsError that gymnasium's wrappers also recognise."""


ACTION_TYPES = ("twist", "joint")
REWARDS = ("pixels", "normalised")
MIN_IMAGE = 64  # pixels, as CameraConfig accepts


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
        if obs_mode not in OBS_MODES:
            raise choice_error("obs_mode", obs_mode, OBS_MODES)
        if appearance not in APPEARANCES:
            raise choice_error("appearance", appearance, APPEARANCES)
        if joints not in JOINT_OBS:
            raise choice_error("joints", joints, JOINT_OBS)
        if tracker != "ground_truth":
            if obs_mode != "features":
                raise ConfigError(f"tracker={tracker!r} fills the 'features' observation: give obs_mode='features'")
            from hvs_sim.plugins import check_any_tracker

            check_any_tracker(tracker)
        for name, v in zip(("render width", "render height"), render_size, strict=True):
            check_number(name, v, 64, 4096, integer=True)
        if action_type not in ACTION_TYPES:
            raise choice_error("action_type", action_type, ACTION_TYPES)
        if reward not in REWARDS:
            raise choice_error("reward", reward, REWARDS)
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
        self.render_size = tuple(render_size)
        self.scenario_name = scenario
        self.base = make_scenario(scenario, mount="arm", camera=CameraConfig(width=width, height=height, sensor=camera),
                                  arm=arm)
        self.tracker = None
        self.max_offset, self.max_roll = max_offset, max_roll
        self.converge_px, self.hold_steps = converge_px, hold_steps
        self.scale = np.array([max_linear] * 3 + [max_angular] * 3)
        self.scene = self.renderer = None
        self.appearance, self._look_seed = appearance, None
        self._compiled = None  # the last episode's Scene: its model and rendering context, kept for restart
        self.model_builds = 0  # scenes built and compiled (the rest of the resets restarted one)
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

    def _obs(self):
        frame = None if self.obs_mode == "features" and self.tracker is None else self.renderer.rgb()
        q, qd = self.scene.joint_positions, self.scene.joint_velocities
        if self.joint_obs == "wrapped":
            joints = np.concatenate([(q + np.pi) % (2 * np.pi) - np.pi, qd])
        else:
            joints = np.concatenate([np.sin(q), np.cos(q), qd])
        obs = {"joints": joints}
        if self.obs_mode == "features":  # with a tracker, its box's corners and where they go at the goal
            desired = self.desired if self.tracker is None else self.tracked_desired
            obs.update(features=self._features(frame), desired=desired.copy())
        else:
            obs["image"] = frame
        if self.obs_mode.startswith("image+goal"):
            obs.update(goal=self.goal.copy(), desired=self.desired.copy())
        if self.obs_mode == "image+goal+depth":
            obs["depth"] = np.clip(self.renderer.depth(), 0.0, MAX_DEPTH_M).astype(np.float32)
        return obs

    def _features(self, frame: np.ndarray) -> np.ndarray:
        """The target's corners now: the truth, or the tracker's (its last good answer when it faults)."""
        if self.tracker is None:
            return self.renderer.ground_truth(occlusion=False, counts=False).corners.astype(np.float64)
        if self._fresh:  # the episode's first frame is the one the tracker was initialised on
            self._fresh = False
            return np.asarray(self._tracked, np.float64).copy()
        try:
            track = self.tracker.update(frame)
            if not np.all(np.isfinite(track.corners)):
                raise FloatingPointError("tracker returned non-finite corners")
            self._tracked, self._tracker_mode, self._tracker_fault = track.corners, str(track.mode), None
        except Exception as exc:  # noqa: BLE001 - a tracker fault is reported in info, the episode goes on
            self._tracker_mode, self._tracker_fault = "fault", f"{type(exc).__name__}: {exc}"
        return np.asarray(self._tracked, np.float64).copy()

    def _info(self, err: float, converged: bool) -> dict:
        info = {"error_px": err, "occlusion": self._occlusion, "converged": converged, "is_success": converged,
                "held_steps": self._held, "K": self.renderer.K.copy(), "camera_pose": self.renderer.camera_pose().matrix()}
        if self.tracker is not None:
            info.update(tracker_mode=self._tracker_mode, tracker_fault=self._tracker_fault)
        return info

    def _error(self) -> float:
        gt = self.renderer.ground_truth(occlusion=True)
        self._occlusion = float(gt.occlusion)
        return float(np.linalg.norm(gt.corners - self.desired, axis=1).mean())

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
            base = make_scenario(options.get("scenario", self.scenario_name), mount="arm", arm=self.base.arm,
                                 camera=CameraConfig(width=cam.width, height=cam.height,
                                                     sensor=options.get("camera", cam.sensor)),
                                 **({"people": options["people"]} if "people" in options else {}))
        except ConfigError as exc:
            raise InputError(f"reset options: {exc}") from None
        return base

    def reset(self, *, seed=None, options=None):
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0):
            raise InputError(f"seed must be None or a non-negative integer, got {seed!r}")
        super().reset(seed=None if seed is None else int(seed))
        from hvs_sim.render.renderer import Renderer
        from hvs_sim.scene.world import Scene, model_key

        if seed is not None:  # a seeded reset draws its look again, so that it repeats from any earlier state
            self._look_seed = None

        base = self._episode_scenario(options)
        rng = self.np_random
        from hvs_sim.servo.teach import check_start_in_view

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
            self.scene = None  # until a start pose is usable
            try:  # a start the arm cannot reach or with the target out of view: a drawn one is drawn again
                if self._compiled is not None and model_key(scen) == model_key(self._compiled.scenario):
                    self._compiled.restart(scen)
                else:
                    self._compiled = None  # the old model's memory goes before the new one is built
                    self._compiled = Scene(scen, framebuffer=self.render_size if self.render_mode == "rgb_array" else None)
                    self.model_builds += 1
                renderer = Renderer(self._compiled, noise_seed=noise)
                check_start_in_view(self._compiled, renderer)
                self.scene, self.renderer = self._compiled, renderer
                break
            except ConfigError as exc:
                if given or draw == START_DRAWS - 1:
                    raise InputError(f"no usable start pose ({exc})") from None
        ref_pos, ref_R = self.scene.reference_pose()
        self.desired = self.renderer.project(CameraPose(ref_R, ref_pos), self.scene.target_corners_world())
        if self.obs_mode.startswith("image+goal"):
            teacher = Renderer(self.scene, people=False)
            with self.scene.posed(self.scene.reference_configuration()):
                self.goal = teacher.rgb()
        self.arm = ArmDriver(self.scene)
        self._held = 0
        self._start_tracker()
        err = self._error()
        return self._obs(), self._info(err, False)

    def _start_tracker(self) -> None:
        """With a tracker: its template at the target's box in the episode's first frame."""
        self.tracker = None
        if self.tracker_name == "ground_truth":
            return
        from hvs_sim.plugins import make_any_tracker
        from hvs_sim.tracking.frames import roi_corners, roi_from_corners

        self.tracker = make_any_tracker(self.tracker_name)
        self.flag0 = self.renderer.ground_truth(occlusion=False, counts=False).corners
        roi = roi_from_corners(self.flag0)
        self.roi0 = roi_corners(roi)  # the tracked box's corners in the first frame; s* is where they go at the goal
        self.tracked_desired = self.renderer.transfer(self.flag0, self.desired, self.roi0)
        try:
            track = self.tracker.init(self.renderer.rgb(), roi)
        except Exception as exc:  # the episode cannot give features: say so, as the loop does
            raise StateError(f"tracker {self.tracker_name!r} could not start on the first frame: "
                             f"{type(exc).__name__}: {exc}") from exc
        self._tracked = self.roi0 if track is None else track.corners  # an outside tracker's init may answer nothing
        self._tracker_mode, self._tracker_fault, self._fresh = "init", None, True

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
        if self.action_type == "twist":
            qdot = self.arm.command(a * self.scale).qdot
        else:
            qdot = a * self.arm.limits.qdot_max
        self.scene.advance(qdot)
        err = self._error()
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
        self.scene = self.renderer = self._compiled = None
