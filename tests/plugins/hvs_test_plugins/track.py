"""A KLT tracker: corners inside the target followed by pyramidal Lucas–Kanade from the template image (no drift),
started where the last homography puts them, and a RANSAC homography to the template.

It imports nothing from hvs_sim: its answers are plain dicts, as an outside tracker may give them.
"""

import cv2
import numpy as np

INSET = 8  # px


class KLTHomography:
    warp = "homography"  # its corners observe all six DOFs

    def __init__(self, max_points: int = 200):
        self.max_points = max_points

    def init(self, frame, roi):
        x, y, w, h = roi
        grey = cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY)
        mask = np.zeros_like(grey)
        m = min(INSET, w // 4, h // 4)  # corners this far inside: their LK windows see the target, not around it
        mask[y + m:y + h - m, x + m:x + w - m] = 255
        pts = cv2.goodFeaturesToTrack(grey, self.max_points, 0.01, 3, mask=mask)
        if pts is None or len(pts) < 8:
            raise ValueError("too few corners in the ROI to track")
        self.p0 = pts.reshape(-1, 2).astype(np.float32)
        self.corners0 = np.array([[x - 0.5, y - 0.5], [x + w - 0.5, y - 0.5], [x + w - 0.5, y + h - 0.5],
                                  [x - 0.5, y + h - 0.5]], np.float64)
        self.prev, self.guess, self.H = grey, self.p0.copy(), np.eye(3)  # prev: the template image
        return {"corners": self.corners0}

    def seed(self, A):
        """The template came from another image (the goal): the points start from where A puts them in the next
        frame."""
        self.H = np.asarray(A, float) / A[2, 2]
        self.guess = cv2.perspectiveTransform(self.p0[None].astype(np.float64), self.H)[0].astype(np.float32)

    def update(self, frame):
        grey = cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY)
        nxt, status, _ = cv2.calcOpticalFlowPyrLK(self.prev, grey, self.p0, self.guess.copy(), winSize=(15, 15),
                                                  maxLevel=3, flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        ok = status.reshape(-1) == 1
        mode = "lost"
        if ok.sum() >= 8:
            H, inliers = cv2.findHomography(self.p0[ok], nxt[ok], cv2.RANSAC, 2.0)
            if H is not None and inliers.sum() >= max(8, 0.5 * ok.sum()):
                self.H, mode = H, "align"
        self.guess = cv2.perspectiveTransform(self.p0[None].astype(np.float64), self.H)[0].astype(np.float32)
        return {"corners": cv2.perspectiveTransform(self.corners0[None], self.H)[0], "mode": mode}


def make(**settings):
    return KLTHomography(**settings)


class Flaky(KLTHomography):
    """Every 5th update answers non-finite corners, every 7th raises: the loop must record both as faults."""

    n = 0

    def update(self, frame):
        out = super().update(frame)
        self.n += 1
        if self.n % 7 == 0:
            raise RuntimeError("flaky tracker gave up on this frame")
        if self.n % 5 == 0:
            out["corners"] = np.full((4, 2), np.nan)
        return out


def make_flaky(**settings):
    return Flaky(**settings)
