"""The one interface every servo law answers, built-in or brought by a user: `compute(ControlInput) -> twist`.

A law is given, each step, the current and desired features (normalised points x = (u − cx)/fx, and the same in
pixels of the undistorted pinhole image), an estimate of each point's depth, the intrinsics K, the camera's own
motion since the last step (from the arm's forward kinematics, as a robot reports it), the tracker's mode and,
for photometric laws, the current frame and the goal image. It returns a 6-vector camera twist (camera frame,
OpenCV axes: x right, y down, z forward; m/s and rad/s) and the DOFs it commands (`Command`). IBVS, PBVS and
photometric servoing (DVS) are built on it, and outside laws are driven through it in the same way
(hvs_sim.plugins).

A policy (learned image-to-velocity servoing) replaces tracker + law: `act(PolicyInput) -> twist`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DOF_NAMES = ("vx", "vy", "vz", "wx", "wy", "wz")


@dataclass(frozen=True)
class ControlInput:
    features: np.ndarray  # (N, 2) current features, normalised coordinates
    desired: np.ndarray  # (N, 2) s*, normalised coordinates
    depths: np.ndarray  # (N,) depth estimate of each current feature (m): from the apparent size, or the simulator's
    desired_depth: float  # Z* (m), the target's depth at the goal
    K: np.ndarray  # (3, 3) pinhole intrinsics
    features_px: np.ndarray  # (N, 2) the current features in pixels (undistorted pinhole image)
    desired_px: np.ndarray  # (N, 2) s* in pixels
    mode: str = "align"  # the tracker's mode: align | predict | lost
    # (4, 4): the current camera pose in the previous step's camera frame (forward kinematics); identity at step 0
    camera_motion: np.ndarray = field(default_factory=lambda: np.eye(4))
    dt: float = 1.0 / 30.0  # s between steps
    image: np.ndarray | None = None  # the current frame (H, W, 3) uint8, for photometric laws
    goal_image: np.ndarray | None = None  # the goal image (H, W, 3) uint8 (teach-by-showing), when the loop took one
    step: int = 0


@dataclass(frozen=True)
class Command:
    """A law's answer: the camera twist and the DOFs it commands (the others are zero)."""

    twist: np.ndarray  # (6,)
    dofs: tuple[str, ...] = DOF_NAMES


@dataclass(frozen=True)
class PolicyInput:
    image: np.ndarray  # the current frame (H, W, 3) uint8
    joints: np.ndarray  # the arm's joint positions (rad)
    goal_image: np.ndarray  # the goal image (the camera at the reference pose, people left out)
    K: np.ndarray  # (3, 3) pinhole intrinsics
    desired_px: np.ndarray  # (4, 2) the target's corners in the goal image (pixels)
    dt: float = 1.0 / 30.0
    step: int = 0


def check_twist(value, who: str) -> np.ndarray:
    """A law's or policy's output as a finite 6-vector; ValueError saying what was wrong (the loop records it as a
    fault and holds the arm for that step)."""
    twist = getattr(value, "twist", value)
    try:
        twist = np.asarray(twist, float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{who} returned {type(value).__name__}; accepted: a 6-vector camera twist (or a Command)") \
            from None
    if twist.shape != (6,):
        raise ValueError(f"{who} returned a twist of {twist.size} values; accepted: 6 (vx, vy, vz, wx, wy, wz)")
    if not np.all(np.isfinite(twist)):
        raise ValueError(f"{who} returned a non-finite twist {twist.tolist()}")
    return twist


def check_dofs(dofs, who: str) -> tuple[str, ...]:
    """Declared DOFs as a non-empty tuple of DOF_NAMES; ValueError otherwise."""
    try:
        dofs = tuple(dofs)
    except TypeError:
        raise ValueError(f"{who} declared dofs {dofs!r}; accepted: a subset of {', '.join(DOF_NAMES)}") from None
    if not dofs or any(d not in DOF_NAMES for d in dofs):
        raise ValueError(f"{who} declared dofs {dofs!r}; accepted: a non-empty subset of {', '.join(DOF_NAMES)}")
    return tuple(d for d in DOF_NAMES if d in dofs)
