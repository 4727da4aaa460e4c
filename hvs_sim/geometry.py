"""Rotations and the single MuJoCo ↔ OpenCV camera convention, shared by scene and render.

MuJoCo cameras look along their −Z with +Y up; OpenCV cameras look along +Z with +Y down and
+X right. Both frames share X, so the conversion flips Y and Z.
"""

from __future__ import annotations

import numpy as np

_FLIP_YZ = np.diag([1.0, -1.0, -1.0])


def mujoco_to_opencv(xmat: np.ndarray) -> np.ndarray:
    """World-from-camera rotation in OpenCV convention from a MuJoCo camera `xmat` (either way round)."""
    return np.asarray(xmat, float).reshape(3, 3) @ _FLIP_YZ


opencv_to_mujoco = mujoco_to_opencv  # the flip is its own inverse


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def mat_to_quat(R: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternion of a rotation matrix (MuJoCo's order)."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def offset_pose(position: np.ndarray, R_cv: np.ndarray, offset6) -> tuple[np.ndarray, np.ndarray]:
    """Displace an OpenCV-convention camera pose by (dx, dy, dz, roll, pitch, yaw) in its own frame."""
    o = np.zeros(6)
    o[: len(offset6)] = offset6
    pos = np.asarray(position, float) + R_cv @ o[:3]
    R = R_cv @ rot_z(o[3]) @ rot_x(o[4]) @ rot_y(o[5])
    return pos, R


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Axis × angle (rad) of a rotation matrix, through the quaternion: exact down to tiny angles."""
    q = mat_to_quat(R)
    if q[0] < 0:
        q = -q
    n = float(np.linalg.norm(q[1:]))
    if n == 0.0:
        return np.zeros(3)
    return 2.0 * np.arctan2(n, q[0]) * q[1:] / n
