"""Rendered evaluation sequences and the ground-truth track of the template centre.

The tracker follows the ROI centre chosen at frame 0, which is a point on the (planar) flag. Its
true image position in frame t is that point mapped by the homography between the projected flag
corners at frame 0 and at frame t: exact, and independent of how the ROI was rounded.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.render.sequence import render_sequence
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.tracking.frames import roi_center


@dataclass
class Sequence:
    scenario: Scenario
    frames: np.ndarray  # (N, H, W, 3) uint8
    corners: np.ndarray  # (N, 4, 2) ground-truth target corners
    occlusion: np.ndarray  # (N,)
    roi: tuple[int, int, int, int]

    @property
    def gt_track(self) -> np.ndarray:
        """(N, 2) true image position of the ROI centre chosen at frame 0."""
        c = roi_center(self.roi).reshape(1, 1, 2).astype(np.float64)
        out = []
        for k in range(len(self.corners)):
            H = cv2.getPerspectiveTransform(self.corners[0].astype(np.float32), self.corners[k].astype(np.float32))
            out.append(cv2.perspectiveTransform(c, H)[0, 0])
        return np.array(out)


def roi_from_corners(corners: np.ndarray) -> tuple[int, int, int, int]:
    """Integer ROI inside the target's projected outline (axis-aligned box of its inner edges)."""
    x0 = int(np.ceil(np.sort(corners[:, 0])[1]))
    x1 = int(np.floor(np.sort(corners[:, 0])[2]))
    y0 = int(np.ceil(np.sort(corners[:, 1])[1]))
    y1 = int(np.floor(np.sort(corners[:, 1])[2]))
    return x0, y0, x1 - x0 + 1, y1 - y0 + 1


def make_sequence(scenario: Scenario, n_frames: int | None = None, progress: bool = False) -> Sequence:
    frames, gts = render_sequence(scenario, n_frames=n_frames, progress=progress)
    corners = np.array([g.corners for g in gts])
    return Sequence(scenario, frames, corners, np.array([g.occlusion for g in gts]), roi_from_corners(corners[0]))
