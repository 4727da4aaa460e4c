"""Camera twist → joint velocities: damped least squares on the camera Jacobian, with limits.

`ArmDriver` is the one way a camera twist reaches the arm (closed loop, gymnasium env, training data):
it reads what a real arm gives (joint angles, and from them the camera pose and Jacobian by forward
kinematics), never the evaluation ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hvs_sim.errors import InputError


@dataclass(frozen=True)
class ArmLimits:
    qdot_max: np.ndarray  # (n,) rad/s
    q_lower: np.ndarray  # (n,) rad; −inf for unlimited joints
    q_upper: np.ndarray  # (n,)
    margin: float = 0.1  # rad: inside this distance to a limit, motion toward it is stopped
    damping: float = 0.02  # DLS damping μ
    # a redundant arm (more than six joints): its null space pulls each limited joint toward the middle of its range,
    # this fast (rad/s) at a limit (ViSP's joint-limit avoidance as a secondary task); no effect on six joints
    null_gain: float = 0.5


@dataclass
class JointCommand:
    qdot: np.ndarray
    velocity_saturated: bool  # the joint velocity limits scaled the command down
    limit_blocked: tuple[int, ...]  # joints stopped near a position limit


def twist_to_joint_velocities(J: np.ndarray, twist_world: np.ndarray, q: np.ndarray, limits: ArmLimits) -> JointCommand:
    """q̇ = J⁺ ξ + (I − J⁺J) q̇₀ with J⁺ = Jᵀ (J Jᵀ + μ² I)⁻¹, then position-limit blocking and uniform velocity
    scaling. q̇₀ (more than six joints only) moves the arm along its self-motion toward the middle of its joint ranges.

    J: (6, n) world-frame Jacobian [linear; angular] of the camera frame; twist_world: (6,).
    """
    J, twist_world, q = (np.asarray(a, float) for a in (J, twist_world, q))
    if J.ndim != 2 or J.shape[0] != 6 or twist_world.shape != (6,) or q.shape != (J.shape[1],):
        raise InputError(f"need J (6, n), twist (6,) and q (n,), got {J.shape}, {twist_world.shape}, {q.shape}")
    if not (np.isfinite(J).all() and np.isfinite(twist_world).all() and np.isfinite(q).all()):
        raise InputError("Jacobian, twist and joint positions must be finite (a NaN would reach the actuators)")
    mu2 = limits.damping ** 2
    qdot = J.T @ np.linalg.solve(J @ J.T + mu2 * np.eye(6), twist_world)
    if len(q) > 6 and limits.null_gain > 0:
        J_pinv = np.linalg.pinv(J)  # undamped: the projector must leave the camera's motion exactly as it is
        limited = np.isfinite(limits.q_lower) & np.isfinite(limits.q_upper)
        lo, hi = np.where(limited, limits.q_lower, q), np.where(limited, limits.q_upper, q)  # free joints: no pull
        half = np.where(limited, (hi - lo) / 2, 1.0)
        mid = (lo + hi) / 2
        qdot = qdot + (np.eye(len(q)) - J_pinv @ J) @ (limits.null_gain * (mid - q) / half)
    blocked = []
    for i in range(len(q)):
        if (q[i] < limits.q_lower[i] + limits.margin and qdot[i] < 0) or (q[i] > limits.q_upper[i] - limits.margin and qdot[i] > 0):
            qdot[i] = 0.0
            blocked.append(i)
    ratio = float(np.max(np.abs(qdot) / limits.qdot_max))
    saturated = ratio > 1.0
    if saturated:
        qdot = qdot / ratio
    return JointCommand(qdot, saturated, tuple(blocked))


class ArmDriver:
    """Drives a scene's arm by camera twists: q̇ from the joints' forward kinematics, within the joint limits."""

    def __init__(self, scene, damping: float = ArmLimits.damping, margin: float = ArmLimits.margin):
        lower, upper, qdot_max = scene.joint_limits()  # ConfigError without an arm
        self.scene = scene
        self.limits = ArmLimits(qdot_max=qdot_max, q_lower=lower, q_upper=upper, margin=margin, damping=damping)

    def command(self, twist_cam: np.ndarray) -> JointCommand:
        """Joint velocities for a camera-frame twist (v, ω) (m/s, rad/s; OpenCV axes) at the arm's configuration now."""
        _, R = self.scene.camera_pose_cv()  # forward kinematics of the joint angles
        return twist_to_joint_velocities(self.scene.camera_jacobian(), camera_twist_to_world(R, np.asarray(twist_cam, float)),
                                         self.scene.joint_positions, self.limits)


def camera_twist_to_world(R_cv: np.ndarray, twist_cam: np.ndarray) -> np.ndarray:
    """Express a camera-frame twist (v, ω) in world axes (same reference point: the camera centre)."""
    return np.concatenate([R_cv @ twist_cam[:3], R_cv @ twist_cam[3:]])
