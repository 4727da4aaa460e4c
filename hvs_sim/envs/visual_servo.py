"""`hvs_sim/VisualServo-v0`: drive the wrist camera with a bounded twist to centre the target.

Observation: {"image": H×W×3 uint8 wrist-camera frame, "joints": joint angles (wrapped) and velocities}.
Action: a camera twist (vx, vy, vz, wx, wy, wz) in [−1, 1]⁶, scaled by max_linear / max_angular,
or with action_type="joint" joint velocities in [−1, 1]ⁿ scaled by the joint velocity limits.
Reward: minus the ground-truth mean corner error to the desired corners, in pixels of the
observation (`reward="pixels"`, the default) or divided by the image diagonal (`reward="normalised"`,
about −0.5 … 0, easier on a value function).
Terminated when that error stays below `converge_px` for `hold_steps` steps.
info: error_px, occlusion (true share of the target hidden), converged, held_steps. There is no
tracker inside: the policy sees the image, the reward comes from ground truth.

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
from hvs_sim.errors import InputError, StateError, choice_error
from hvs_sim.render.camera import CameraPose
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.validate import check_number


class ResetNeededError(StateError, gym.error.ResetNeeded):
    """step() before reset(): an HvsError that gymnasium's wrappers also recognise."""


ACTION_TYPES = ("twist", "joint")
REWARDS = ("pixels", "normalised")
MIN_IMAGE = 64  # pixels, as CameraConfig accepts


class VisualServoEnv(gym.Env):
    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, scenario: str = "clear", render_mode: str | None = None, action_type: str = "twist",
                 width: int = 160, height: int = 120, max_offset: float = 0.05, max_roll: float = 0.15,
                 converge_px: float = 1.0, hold_steps: int = 5, max_linear: float = 0.1, max_angular: float = 0.5,
                 camera: str = "ideal", reward: str = "pixels"):
        """camera: the camera model of the observations (hvs_sim.camera_model.SENSOR_PRESETS), e.g.
        "phone_handheld" for exposure changes, blur, noise and JPEG as a real camera gives them."""
        if render_mode not in (None, "rgb_array"):
            raise choice_error("render_mode", render_mode, ["rgb_array", "None"])
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
        self.base = make_scenario(scenario, mount="arm", camera=CameraConfig(width=width, height=height, sensor=camera))
        self.max_offset, self.max_roll = max_offset, max_roll
        self.converge_px, self.hold_steps = converge_px, hold_steps
        self.scale = np.array([max_linear] * 3 + [max_angular] * 3)
        self.scene = self.renderer = None
        n = 6
        self.observation_space = spaces.Dict({
            "image": spaces.Box(0, 255, (height, width, 3), np.uint8),
            # angles wrapped to [−π, π); velocities well inside ±10 rad/s (actuators stop at < 1 rad/s)
            "joints": spaces.Box(np.r_[[-np.pi] * n, [-10.0] * n], np.r_[[np.pi] * n, [10.0] * n], (2 * n,), np.float64),
        })
        self.action_space = spaces.Box(-1.0, 1.0, (6 if action_type == "twist" else n,), np.float32)

    def _obs(self):
        frame = self.renderer.rgb()
        self._frame = frame
        q = (self.scene.joint_positions + np.pi) % (2 * np.pi) - np.pi
        return {"image": frame, "joints": np.concatenate([q, self.scene.joint_velocities])}

    def _error(self) -> float:
        gt = self.renderer.ground_truth(occlusion=True)
        self._occlusion = float(gt.occlusion)
        return float(np.linalg.norm(gt.corners - self.desired, axis=1).mean())

    def reset(self, *, seed=None, options=None):
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0):
            raise InputError(f"seed must be None or a non-negative integer, got {seed!r}")
        super().reset(seed=None if seed is None else int(seed))
        from hvs_sim.render.renderer import Renderer
        from hvs_sim.scene.world import Scene

        rng = self.np_random
        offset = (*rng.uniform(-self.max_offset, self.max_offset, 3), rng.uniform(-self.max_roll, self.max_roll))
        scen = dataclasses.replace(self.base, seed=int(rng.integers(0, 2**31 - 1)), start_offset=tuple(float(v) for v in offset))
        self.scene = Scene(scen)
        self.renderer = Renderer(self.scene)
        ref_pos, ref_R = self.scene.reference_pose()
        self.desired = self.renderer.project(CameraPose(ref_R, ref_pos), self.scene.target_corners_world())
        self.arm = ArmDriver(self.scene)
        self._held = 0
        err = self._error()
        return self._obs(), {"error_px": err, "occlusion": self._occlusion, "converged": False, "held_steps": 0}

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
        info = {"error_px": err, "occlusion": self._occlusion, "converged": terminated, "held_steps": self._held}
        return self._obs(), -err * self.reward_scale, terminated, False, info

    def render(self):
        if self.scene is None:
            raise ResetNeededError("call reset() before render()")
        if self.render_mode == "rgb_array":
            return self._frame.copy()
        return None

    def close(self):
        self.scene = self.renderer = None
