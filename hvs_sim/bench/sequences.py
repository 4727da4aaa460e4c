"""Rendered evaluation sequences and the ground-truth track of the template centre.

The tracker follows the ROI centre chosen at frame 0, which is a point on the (planar) flag. Its
true image position in frame t is that point mapped by the homography between the projected flag
corners at frame 0 and at frame t: exact, and independent of how the ROI was rounded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hvs_sim.render.camera import transfer_points
from hvs_sim.render.renderer import Renderer
from hvs_sim.render.sequence import render_sequence
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.tracking.frames import roi_center, roi_from_corners


@dataclass
class Sequence:
    scenario: Scenario
    frames: np.ndarray  # (N, H, W, 3) uint8
    corners: np.ndarray  # (N, 4, 2) ground-truth target corners
    occlusion: np.ndarray  # (N,)
    roi: tuple[int, int, int, int]
    K: np.ndarray | None = None  # intrinsics and lens distortion, so that the ground-truth track stays exact
    distortion: tuple[float, ...] = ()

    @property
    def gt_track(self) -> np.ndarray:
        """(N, 2) true image position of the ROI centre chosen at frame 0."""
        c = roi_center(self.roi)[None]
        return np.array([transfer_points(self.corners[0], corners, c, self.K, self.distortion)[0] for corners in self.corners])


def make_sequence(scenario: Scenario, n_frames: int | None = None, progress: bool = False) -> Sequence:
    frames, gts = render_sequence(scenario, n_frames=n_frames, progress=progress)
    corners = np.array([g.corners for g in gts])
    return Sequence(scenario, frames, corners, np.array([g.occlusion for g in gts]), roi_from_corners(corners[0]),
                    K=Renderer.intrinsics_of(scenario), distortion=scenario.camera.sensor.distortion)
