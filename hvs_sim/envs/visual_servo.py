"""`hvs_sim/VisualServo-v0`: drive the wrist camera with a bounded twist to centre the target.

Observation: {"image": H×W×3 uint8 wrist-camera frame, "joints": joint angles (wrapped) and velocities}.
Action: a camera twist (vx, vy, vz, wx, wy, wz) in [−1, 1]⁶, scaled by max_linear / max_angular,
or with action_type="joint" joint velocities in [−1, 1]ⁿ scaled by the joint velocity limits.
Reward: minus the ground-truth mean corner error to the desired corners (pixels).
Terminated when that error stays below `converge_px` for `hold_steps` steps.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from hvs_sim.control.arm import ArmLimits, camera_twist_to_world, twist_to_joint_velocities
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.render.camera import CameraPose
from hvs_sim.scene.scenarios import CameraConfig, make_scenario

ACTION_TYPES = ("twist", "joint")


class VisualServoEnv(gym.Env):
    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, scenario: str = "clear", render_mode: str | None = None, action_type: str = "twist",
                 width: int = 160, height: int = 120, max_offset: float = 0.05, max_roll: float = 0.15,
                 converge_px: float = 1.0, hold_steps: int = 5, max_linear: float = 0.1, max_angular: float = 0.5,
                 camera: str = "ideal"):
        """camera: the camera model of the observations (hvs_sim.camera_model.SENSOR_PRESETS), e.g.
        "phone_handheld" for exposure changes, blur, noise and JPEG as a real camera gives them."""
        if render_mode not in (None, "rgb_array"):
            raise choice_error("render_mode", render_mode, ["rgb_array", "None"])
        if action_type not in ACTION_TYPES:
            raise choice_error("action_type", action_type, ACTION_TYPES)
        if max_linear <= 0 or max_angular <= 0:
            raise ConfigError("max_linear and max_angular must be > 0")
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
        gt = self.renderer.ground_truth(occlusion=False)
        return float(np.linalg.norm(gt.corners - self.desired, axis=1).mean())

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        from hvs_sim.render.renderer import Renderer
        from hvs_sim.scene.world import Scene

        rng = self.np_random
        offset = (*rng.uniform(-self.max_offset, self.max_offset, 3), rng.uniform(-self.max_roll, self.max_roll))
        scen = dataclasses.replace(self.base, seed=int(rng.integers(0, 2**31 - 1)), start_offset=tuple(float(v) for v in offset))
        self.scene = Scene(scen)
        self.renderer = Renderer(self.scene)
        ref_pos, ref_R = self.scene.reference_pose()
        self.desired = self.renderer.project(CameraPose(ref_R, ref_pos), self.renderer.target_corners_world())
        lower, upper, qdot_max = self.scene.joint_limits()
        self.limits = ArmLimits(qdot_max=qdot_max, q_lower=lower, q_upper=upper)
        self._held = 0
        err = self._error()
        return self._obs(), {"error_px": err}

    def step(self, action):
        if self.scene is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        a = np.clip(np.asarray(action, np.float64), -1.0, 1.0)
        if self.action_type == "twist":
            R = self.renderer.camera_pose().R
            cmd = twist_to_joint_velocities(self.scene.camera_jacobian(), camera_twist_to_world(R, a * self.scale),
                                            self.scene.joint_positions, self.limits)
            qdot = cmd.qdot
        else:
            qdot = a * self.limits.qdot_max
        self.scene.advance(qdot)
        err = self._error()
        self._held = self._held + 1 if err < self.converge_px else 0
        terminated = self._held >= self.hold_steps
        return self._obs(), -err, terminated, False, {"error_px": err}

    def render(self):
        if self.render_mode == "rgb_array" and self.scene is not None:
            return self._frame.copy()
        return None

    def close(self):
        self.scene = self.renderer = None
