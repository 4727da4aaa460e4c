"""The arm's inverse kinematics: the joint angles that put the wrist camera at a pose, within the joint limits.

Apart from world.py (the Scene) because it is numerics on a physics and a rig, not the world: dm_control's IK, the
turn of a joint that spans more than one, and a redundant arm brought into its limits along its self-motion. Which
solution a scene starts from (home configuration, continuation, restarts) stays with the Scene.
"""

from __future__ import annotations

import mujoco
import numpy as np
from absl import logging as absl_logging
from dm_control.utils import inverse_kinematics

from hvs_sim.errors import ConfigError
from hvs_sim.geometry import mat_to_quat, opencv_to_mujoco

IK_PROGRESS_THRESH = 1e4  # dm_control stops an IK whose step is this many times its error drop; near the
# wrist singularity progress is slow but real, and the default (20) gave up on reachable poses
IK_LIMIT_STEPS, IK_LIMIT_DAMPING, IK_LIMIT_INSET = 400, 1e-3, 1e-3  # a redundant arm's IK brought into its limits
# deeper than this, an overlap of the arm's geoms (with itself or anything else) is a collision: the physics pushes
# the links apart at its first step (a Jaco folded onto its own link 2 kicked its elbow at 1.4 rad/s, carrying the
# camera 10 cm before the loop had commanded anything), so a start configuration must not have one
MAX_START_PENETRATION_M = 1e-3


def solve_arm_ik(root, physics, rig, position, R_cv, q0) -> np.ndarray:
    scratch = physics.copy(share_model=True)
    joints = scratch.bind(rig.joints)
    if q0 is not None:
        joints.qpos = q0
    names = [j.full_identifier for j in rig.joints]
    quat = mat_to_quat(opencv_to_mujoco(R_cv))
    level = absl_logging.get_verbosity()
    absl_logging.set_verbosity(absl_logging.ERROR)  # a failed solve is an answer here (restarts, a refusal), not news
    try:
        res = inverse_kinematics.qpos_from_site_pose(
            scratch, rig.camera_site.full_identifier, target_pos=position, target_quat=quat,
            joint_names=names, tol=1e-10, max_steps=2000, inplace=True, progress_thresh=IK_PROGRESS_THRESH)
    finally:
        absl_logging.set_verbosity(level)
    if not res.success and res.err_norm > 1e-5:
        raise ConfigError(f"camera pose {np.round(position, 3).tolist()} is out of the arm's reach (IK error {res.err_norm:.2g})")
    q = scratch.bind(rig.joints).qpos.copy()
    limited = physics.model.jnt_limited[physics.bind(rig.joints).element_id].astype(bool)
    lo, hi = np.asarray(physics.bind(rig.joints).range, float).T
    lower, upper = np.where(limited, lo, -np.inf), np.where(limited, hi, np.inf)
    if q0 is not None:  # a joint that turns more than once: the turn nearest the start (the same pose)
        q = unwound(q, q0, lower, upper)
    if len(q) > 6 and np.any(limited & ((q < lo) | (q > hi))):  # a redundant arm: move along its self-motion
        q = _into_limits(scratch, rig, q, position, quat, lower, upper)
    if np.any(limited & ((q < lo) | (q > hi))):
        raise ConfigError(f"camera pose {np.round(position, 3).tolist()} needs an arm configuration outside the "
                          "joint limits")
    return q


def range_middle(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The middle of each joint's range; 0 for a joint without limits."""
    limited = np.isfinite(lower) & np.isfinite(upper)
    return np.where(limited, (np.where(limited, lower, 0.0) + np.where(limited, upper, 0.0)) / 2, 0.0)


def unwound(q: np.ndarray, ref: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """q with each joint whose limits span a full turn or more (a UR's ±2π) moved by whole turns to the value nearest
    `ref` within its limits: the same arm pose, a turn nearer where the arm is (an IK step) or further from the
    limits it would otherwise run into (a restart). Joints without limits, or spanning under a turn, are left alone."""
    q = np.array(q, float)
    wide = np.isfinite(lower) & np.isfinite(upper) & (upper - lower >= 2 * np.pi - 1e-9)
    for i in np.flatnonzero(wide):
        turns = np.arange(np.ceil((lower[i] - q[i]) / (2 * np.pi)), np.floor((upper[i] - q[i]) / (2 * np.pi)) + 1)
        if len(turns):
            q[i] += 2 * np.pi * turns[np.argmin(np.abs(q[i] + 2 * np.pi * turns - ref[i]))]
    return q


def _into_limits(scratch, rig, q, position, quat, lo, hi, steps: int = IK_LIMIT_STEPS) -> np.ndarray:
    """The IK answer of a redundant arm moved along its self-motion into its joint limits: damped least squares on
    the pose error, the null space pulling each joint toward the middle of its range, the joints clipped just inside
    their limits. dm_control's IK ignores limits, and a 7-joint arm's first answer is usually outside them; its
    null space has room to come back in with the camera where it was. Returns q (checked by the caller)."""
    m, d = scratch.model.ptr, scratch.data.ptr
    site = scratch.bind(rig.camera_site).element_id
    dofs = scratch.bind(rig.joints).dofadr
    qpos = scratch.bind(rig.joints)
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), range_middle(lo, hi), q)
    span = np.where(np.isfinite(hi - lo), hi - lo, 2 * np.pi)
    inside_lo, inside_hi = lo + IK_LIMIT_INSET, hi - IK_LIMIT_INSET
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    flat_R = np.zeros(9)
    mujoco.mju_quat2Mat(flat_R, np.asarray(quat, float))
    target_R = flat_R.reshape(3, 3)

    def pose_error() -> np.ndarray:  # (position; rotation vector, small angles) from the site to the target pose
        R = d.site_xmat[site].reshape(3, 3)
        return np.concatenate([position - d.site_xpos[site], 0.5 * sum(np.cross(R[:, k], target_R[:, k]) for k in range(3))])

    for _ in range(steps):
        qpos.qpos = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        err = pose_error()
        mujoco.mj_jacSite(m, d, jacp, jacr, site)
        J = np.vstack([jacp[:, dofs], jacr[:, dofs]])
        J_pinv = J.T @ np.linalg.inv(J @ J.T + IK_LIMIT_DAMPING ** 2 * np.eye(6))
        pull = -(q - mid) / span ** 2
        q = np.clip(q + J_pinv @ err + (np.eye(len(q)) - J_pinv @ J) @ pull, inside_lo, inside_hi)
    qpos.qpos = q
    mujoco.mj_kinematics(m, d)
    if np.linalg.norm(pose_error()) > 1e-6:
        raise ConfigError(f"camera pose {np.round(position, 3).tolist()} needs an arm configuration outside the "
                          "joint limits")
    return q


def arm_collisions(physics, rig, q: np.ndarray) -> list[str]:
    """The arm's collisions at joint angles q (on a copy of the physics): "geom | geom (depth mm)" for each contact
    of an arm geom deeper than MAX_START_PENETRATION_M. dm_control's IK places the camera and knows nothing of them."""
    scratch = physics.copy(share_model=True)
    scratch.bind(rig.joints).qpos = q
    m, d = scratch.model.ptr, scratch.data.ptr
    mujoco.mj_forward(m, d)
    arm = np.zeros(m.nbody, bool)
    arm[m.jnt_bodyid[scratch.bind(rig.joints).element_id]] = True
    for b in range(1, m.nbody):  # bodies come after their parents: the subtrees of the joints' bodies
        arm[b] |= arm[m.body_parentid[b]]
    out = []
    for c in d.contact[:d.ncon]:
        if c.dist < -MAX_START_PENETRATION_M and (arm[m.geom_bodyid[c.geom1]] or arm[m.geom_bodyid[c.geom2]]):
            names = (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or f"geom {g}" for g in (c.geom1, c.geom2))
            out.append(f"{' | '.join(names)} ({-1e3 * c.dist:.1f} mm)")
    return out
