"""Pinhole camera model in OpenCV convention: intrinsics from MuJoCo's fovy, and projection.

Pixel convention: integer coordinates are pixel centres. MuJoCo puts the principal point at the
image centre, which is ((W − 1) / 2, (H − 1) / 2) in that convention; square pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.sensor import distort_points, undistort_points

MAX_STILL_FRAMES = 256  # Renderer.still_average: more frames than a user would grab at the goal


def intrinsics(width: int, height: int, fovy_deg: float) -> np.ndarray:
    """3×3 K of a MuJoCo camera (fovy is the vertical field of view in degrees)."""
    f = 0.5 * height / np.tan(np.radians(fovy_deg) / 2)
    return np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CameraPose:
    """Camera pose in the world, OpenCV convention: p_world = R @ p_cam + t."""

    R: np.ndarray
    t: np.ndarray

    def to_camera(self, points_world: np.ndarray) -> np.ndarray:
        return (np.atleast_2d(np.asarray(points_world, float)) - self.t) @ self.R

    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.R, self.t
        return T


def transfer_points(corners_from: np.ndarray, corners_to: np.ndarray, pts: np.ndarray, K: np.ndarray | None = None,
                    distortion: tuple[float, ...] = ()) -> np.ndarray:
    """Map image points of a planar target through the homography between two views of its corners.

    With a distorting lens (K and OpenCV distortion coefficients) the homography holds between the
    undistorted views only: points are undistorted first and distorted again after, so it stays exact.
    """
    if distortion:
        # K is given wherever distortion is (Renderer.transfer)
        corners_from, corners_to, pts = (undistort_points(K, distortion, a)  # type: ignore[arg-type]
                                         for a in (corners_from, corners_to, pts))
    H = cv2.getPerspectiveTransform(np.asarray(corners_from, np.float32), np.asarray(corners_to, np.float32))
    out = cv2.perspectiveTransform(np.asarray(pts, np.float64).reshape(1, -1, 2), H)[0]
    return distort_points(K, distortion, out) if distortion else out  # type: ignore[arg-type]  # K: as above


def project(K: np.ndarray, pose: CameraPose, points_world: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N, 2) of world points; points behind the camera give NaN."""
    pc = pose.to_camera(np.atleast_2d(points_world))
    z = pc[:, 2:3]
    uv = (pc[:, :2] / np.where(z > 1e-9, z, np.nan)) @ K[:2, :2].T + K[:2, 2]
    return uv
