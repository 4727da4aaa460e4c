"""Ground truth of one frame: the record (`GroundTruth`) and the geometry behind the occlusion it reports.

Apart from renderer.py because this part is geometry on arrays (the target's outline box, the pixels of a mask inside
a polygon, whether a person's bounding boxes can reach the target's image), not rendering: the Renderer draws the
segmentation render and asks these.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.render.camera import CameraPose

CUBE_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
MIN_DEPTH_M = 1e-3  # a person's geom closer to the camera plane than this may cover anything
OUTLINE_SHIFT = 4  # the target's outline is rasterised with 2^-4 px vertex precision
OUTLINE_SUBPIXEL = 1 << OUTLINE_SHIFT
SEG_BOX_MARGIN_PX = 12  # the occlusion count decodes the target's outline box grown by this: its 4 mm thick edges show


@dataclass(frozen=True)
class GroundTruth:
    """What is true at one frame. Pixel values use the pixel-centre convention."""

    frame: int
    time: float
    center: np.ndarray  # (2,) projected centre of the target flag
    corners: np.ndarray  # (4, 2) TL, TR, BR, BL
    occlusion: float  # share of the target's pixels hidden by people, from segmentation renders
    visible_px: int | None  # None: not counted (ground_truth(counts=False) with nobody over the target)
    full_px: int | None
    camera: CameraPose
    target_depth: float  # z of the target centre in the camera frame (m)
    joint_positions: np.ndarray
    target_world: np.ndarray | None = None  # (4, 3) the target's corners in the world (m), TL, TR, BR, BL

    def as_row(self) -> dict:
        return {
            "frame": self.frame, "time": round(self.time, 6), "cx": self.center[0], "cy": self.center[1],
            **{f"{a}{i}": self.corners[i, j] for i in range(4) for j, a in enumerate("xy")},
            "occlusion": self.occlusion, "visible_px": self.visible_px, "full_px": self.full_px,
            "depth": self.target_depth,
        }


def outline_box(outline_px: np.ndarray, width: int, height: int) -> tuple[slice, slice] | None:
    """(rows, cols) slices of the target's outline box grown by SEG_BOX_MARGIN_PX and clipped to the image (empty when
    the outline is outside it); None when a corner is not finite (behind the camera): the whole frame is decoded."""
    uv = outline_px
    if not np.all(np.isfinite(uv)):
        return None
    x0, y0 = np.clip(np.floor(uv.min(axis=0)).astype(int) - SEG_BOX_MARGIN_PX, 0, [width, height])
    x1, y1 = np.clip(np.ceil(uv.max(axis=0)).astype(int) + SEG_BOX_MARGIN_PX, 0, [width, height])
    return (slice(y0, y1), slice(x0, x1)) if x1 > x0 and y1 > y0 else (slice(0, 0), slice(0, 0))


def count_inside(mask: np.ndarray, outline_px: np.ndarray, box: tuple[slice, slice]) -> int:
    """The pixels of `mask` (the size of `box`, whose corner is at box's starts) inside the polygon `outline_px`,
    rasterised at 1/OUTLINE_SUBPIXEL px."""
    x0, y0 = box[1].start, box[0].start
    outline = np.zeros(mask.shape, np.uint8)
    cv2.fillPoly(outline, [np.round((outline_px - [x0, y0]) * OUTLINE_SUBPIXEL).astype(np.int32)], 1,
                 lineType=cv2.LINE_8, shift=OUTLINE_SHIFT)
    return int(np.count_nonzero(mask & (outline > 0)))


def boxes_may_cover(model, data, geoms: np.ndarray, pose: CameraPose, K: np.ndarray, outline_px: np.ndarray) -> bool:
    """False only when none of the geoms `geoms` (a mask over geom ids) can appear over the target in the (undistorted)
    view: each geom lies in its bounding box (MuJoCo's geom_aabb, posed), whose image is the hull of its projected
    corners (perspective keeps convex sets convex in front of the camera), and no such hull meets the target's image
    (outline_px: `Renderer.target_outline`)."""
    aabb = np.asarray(model.geom_aabb)[geoms]  # (G, 6): centre, half sizes, geom frame
    local = aabb[:, None, :3] + aabb[:, None, 3:] * CUBE_CORNERS[None]  # (G, 8, 3)
    xmat = np.asarray(data.geom_xmat)[geoms].reshape(-1, 3, 3)
    world = np.asarray(data.geom_xpos)[geoms][:, None, :] + local @ xmat.transpose(0, 2, 1)
    cam = (world - pose.t) @ pose.R
    if np.any(cam[..., 2] <= MIN_DEPTH_M):
        return True  # a box reaches the camera plane: its image is unbounded
    uv = cam[..., :2] / cam[..., 2:] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    if not np.all(np.isfinite(outline_px)):
        return True
    lo, hi = outline_px.min(axis=0) - 1.0, outline_px.max(axis=0) + 1.0
    return bool(np.any(np.all((uv.max(axis=1) >= lo) & (uv.min(axis=1) <= hi), axis=1)))
