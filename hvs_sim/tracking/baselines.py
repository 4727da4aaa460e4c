"""The paper's classical baselines behind the tracker contract: SIFT + RANSAC and OpenCV ECC."""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.tracking.base import Estimate, Tracker
from hvs_sim.tracking.ecc import check_gauss, ecc_template, find_transform
from hvs_sim.tracking.frames import to_grey
from hvs_sim.tracking.occlusion import TAU_PIX, OcclusionReference, aligned_patch
from hvs_sim.tracking.warp import check_warp, project_similarity
from hvs_sim.validate import check_number

SIFT_HOMOGRAPHY_MIN = 8  # matches before a homography is fitted (4 fit one exactly, with nothing to check it)


class _GreyTemplate(Tracker):
    """Shared part: the grey template at full resolution and OP_t against it."""

    def _init(self, frame, roi) -> None:
        self._set_template(to_grey(frame), roi)

    def _set_template(self, grey: np.ndarray, roi) -> None:
        x, y, w, h = roi
        self.template = grey[y:y + h, x:x + w].copy()
        self.reference = OcclusionReference(self.template, TAU_PIX)
        self.origin = np.array([x, y], float)

    def occlusion(self, grey: np.ndarray, A: np.ndarray) -> float:
        patch, inside = aligned_patch(grey, A, self.origin, self.template.shape)
        return self.reference(patch, inside)


class SiftTracker(_GreyTemplate):
    """SIFT keypoints of the template matched in every frame (ratio test), RANSAC similarity (or homography)."""

    name = "sift"

    def __init__(self, ratio: float = 0.75, min_inliers: int = 6, ransac_px: float = 3.0, warp: str = "similarity"):
        super().__init__()
        self.warp = check_warp(warp)
        check_number("sift ratio", ratio, 0, 1, lo_open=True, hi_open=True)
        check_number("sift min_inliers", min_inliers, 3, integer=True)  # a similarity needs 2 points, RANSAC a spare
        check_number("sift ransac_px", ransac_px, 0, lo_open=True)
        self.ratio, self.min_inliers, self.ransac_px = ratio, min_inliers, ransac_px
        self.sift = cv2.SIFT_create()
        self.matcher = cv2.BFMatcher(cv2.NORM_L2)

    def _init(self, frame, roi) -> None:
        super()._init(frame, roi)
        kps, self.desc = self.sift.detectAndCompute(self.template, None)
        self.pts = np.array([k.pt for k in kps], np.float32).reshape(-1, 2) + self.origin.astype(np.float32)

    def _update(self, frame) -> Estimate:
        grey = to_grey(frame)
        if self.desc is None or len(self.pts) < self.min_inliers:
            return Estimate(self.A, "lost", 1.0, 0.0)
        kps, desc = self.sift.detectAndCompute(grey, None)
        if desc is None or len(kps) < 2:
            return Estimate(self.A, "lost", 1.0, 0.0)
        good = [m for m, n in (p for p in self.matcher.knnMatch(self.desc, desc, k=2) if len(p) == 2)
                if m.distance < self.ratio * n.distance]
        if len(good) < self.min_inliers:
            return Estimate(self.A, "lost", self.occlusion(grey, self.A), len(good) / max(len(self.pts), 1))
        src = self.pts[[m.queryIdx for m in good]]
        dst = np.array([kps[m.trainIdx].pt for m in good], np.float32)
        if self.warp == "homography" and len(good) >= SIFT_HOMOGRAPHY_MIN:
            M, inliers = cv2.findHomography(src, dst, cv2.RANSAC, self.ransac_px)
        else:
            M, inliers = cv2.estimateAffinePartial2D(src, dst, method=cv2.RANSAC, ransacReprojThreshold=self.ransac_px)
        n_in = int(inliers.sum()) if inliers is not None else 0
        score = n_in / max(len(self.pts), 1)
        if M is None or n_in < self.min_inliers or not np.all(np.isfinite(M)):
            return Estimate(self.A, "lost", self.occlusion(grey, self.A), score)
        A = M / M[2, 2] if M.shape == (3, 3) else np.vstack([M, [0, 0, 1.0]])
        return Estimate(A, "align", self.occlusion(grey, A), score)


class EccTracker(_GreyTemplate):
    """OpenCV ECC (the paper's "LK-only") from the previous estimate: affine, projected to a similarity
    (or a homography with warp="homography"). The template is cut from the pre-filtered frame (ecc.py)."""

    name = "ecc"

    def __init__(self, iterations: int = 50, eps: float = 1e-4, gauss: int = 5, warp: str = "similarity"):
        super().__init__()
        self.warp = check_warp(warp)
        check_number("ecc iterations", iterations, 1, integer=True)
        check_number("ecc eps", eps, 0, lo_open=True)
        check_gauss(gauss, "ecc gauss")
        self.criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, iterations, eps)
        self.gauss = gauss

    def _init(self, frame, roi) -> None:
        grey = to_grey(frame)
        self._set_template(grey, roi)
        self.template_ecc = ecc_template(grey, roi, self.gauss)

    def _update(self, frame) -> Estimate:
        grey = to_grey(frame)
        T = np.array([[1, 0, self.origin[0]], [0, 1, self.origin[1]], [0, 0, 1.0]])
        homography = self.warp == "homography"
        W = (self.A @ T) if homography else (self.A @ T)[:2]  # template pixel → frame pixel
        motion = cv2.MOTION_HOMOGRAPHY if homography else cv2.MOTION_AFFINE
        try:
            score, W = find_transform(self.template_ecc, grey, W, motion, self.criteria, None, self.gauss)
        except cv2.error:  # raised when ECC does not converge or the frame is degenerate
            return Estimate(self.A, "lost", self.occlusion(grey, self.A), 0.0)
        if homography:
            A = W.astype(float) @ np.linalg.inv(T)
            A /= A[2, 2]
        else:
            A = project_similarity(np.vstack([W, [0, 0, 1.0]]) @ np.linalg.inv(T), self.center0)
        return Estimate(A, "align", self.occlusion(grey, A), float(score))
