"""The planar target's pose from its corners, as the controller knows the target: the desired corners s* seen at the
desired depth Z* with the target's plane facing the camera. PBVS servos on that pose; the feature filter carries
its last estimate by the homography that plane induces between two views (control/feature_filter.py)."""

from __future__ import annotations

import cv2
import numpy as np


def target_model(desired_px: np.ndarray, desired_depth: float, K: np.ndarray) -> np.ndarray:
    """The planar target (N, 3) as the controller knows it: the desired corners s* back-projected at depth Z*."""
    s = (np.asarray(desired_px, float).reshape(-1, 2) - K[:2, 2]) / np.diag(K)[:2]
    return np.column_stack([s * desired_depth, np.full(len(s), desired_depth)])


def target_pose(model: np.ndarray, K: np.ndarray, corners_px: np.ndarray,
                refine: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """(R, t) of the planar `model` in the camera frame from its corners (pixels): cv2.solvePnP with IPPE; None when
    OpenCV finds no finite pose (a degenerate quad). IPPE fits the plane's homography to the four corners exactly
    (eight numbers) and reads the pose off it, so corner noise in the homography's two projective parameters lands
    in the pose too; `refine` then minimises the reprojection error over the pose's six parameters
    (cv2.solvePnPRefineLM): the least-squares pose, whose noise is what L⁺ makes of the corners' (PBVS)."""
    pts = np.asarray(corners_px, np.float64).reshape(-1, 1, 2)
    try:
        ok, rvec, tvec = cv2.solvePnP(model, pts, K, None, flags=cv2.SOLVEPNP_IPPE)
        if ok and refine and np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec)):
            rvec, tvec = cv2.solvePnPRefineLM(model, pts, K, None, rvec, tvec)
    except cv2.error:
        return None
    if not ok or not np.all(np.isfinite(rvec)) or not np.all(np.isfinite(tvec)):
        return None
    return cv2.Rodrigues(rvec)[0], tvec.reshape(3)
