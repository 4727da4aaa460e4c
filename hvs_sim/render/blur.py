"""Motion blur from the image motion field: one render at mid-exposure, blurred along each pixel's path.

Every pixel's 3-D point is known from the render's depth; where that point is at the start and at the end of the
exposure follows from the camera's motion and, for the pixels of a moving body (a person, a sliding wall), the
body's own rigid motion. Its image path over the exposure is taken as the straight line from its start to its end, centred on the
mid-exposure pixel. The pixel collects, at each instant, the light of the point whose path passes over it then; to first
order that is the mid-exposure image sampled at the pixel mirrored along its own path (a gather along the local
flow, as post-process motion blur does). Taps are BLUR_STEP_PX apart along the longest path, as the sub-frame
reference spaces its renders (`SensorModel.blur = "subframes"`), so a frame costs one render, one depth read-back
and a remap per tap instead of a render per sub-frame. The paths are found on a grid every FIELD_STRIDE pixels. Where the flow changes abruptly (a person's edge
over the wall) the gather smears the wrong side: tests/test_sensor.py measures that error against the reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.render.camera import CameraPose, project
from hvs_sim.sensor import BLUR_STEP_PX, FIELD_MAX_TAPS, LUMA

FIELD_STRIDE = 2  # the paths are found every this many pixels and interpolated between (the field is smooth but at
# depth edges, where the gather is approximate anyway): a quarter of the arithmetic
PERSON_PROBE_HEIGHTS = (0.5, 1.2, 1.7)  # m above the feet: points whose image motion sets the blur sampling
BLUR_PROBE_MARGIN = 0.25  # ... counted while within this fraction of the image size outside the frame
PERSON_DEPTH_TOL_RAW = 1e-6  # field blur: a pixel is a person's where the people-only render's raw depth is the full
# render's (the same fragment: the same value, up to this)
BODY_BOX_MARGIN_M = 0.005  # field blur: a point within this of the moving wall's boxes rides on the wall
GRADIENT_FLOOR = 0.02  # combine_subframes: linear light per small pixel under which a gradient cannot say how far the
# image moved (a flat area, where the sub-frames agree anyway and the detail is kept)


@dataclass(frozen=True)
class Rigid:
    """A pose (rotation R, translation t): world point = R @ local point + t."""

    R: np.ndarray
    t: np.ndarray

    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.R, self.t
        return T


def moving_labels(r, raw: np.ndarray, points: np.ndarray, k: int) -> np.ndarray:
    """uint8 labels of the raw depth `raw` of the Renderer `r`'s last render (every k-th pixel; `points` its
    camera-frame points): 0 where the pixel shows the still world, j where it shows the j-th of `r`'s moving bodies
    (the people shown, then the wall if it slides). A person's pixels are those where a people-only render (cheap:
    few fragments) is as near as the full one; the nearest person's feet (in plan) say whose. The wall's are the
    points inside its boxes."""
    scene = r.scene
    labels = np.zeros(raw.shape, np.uint8)
    people = [p.body for p in scene.people] if r.people else []
    pose = r.camera_pose()
    world = None  # the points in the world, when a test needs them
    if people:
        only = r._depth_buffer(r._only_people)[::k, ::k]
        mine = (only < 1.0) & (only <= raw + PERSON_DEPTH_TOL_RAW)
        if len(people) == 1:
            labels[mine] = 1
        elif np.any(mine):
            world = points @ pose.R.T + pose.t
            feet = np.array([scene.physics.bind(b).xpos[:2] for b in people])
            d = np.linalg.norm(world[mine][:, None, :2] - feet[None], axis=-1)
            labels[mine] = 1 + np.argmin(d, axis=1).astype(np.uint8)
    if any(scene.scenario.wall_motion):
        world = points @ pose.R.T + pose.t if world is None else world
        lo, hi = wall_box(scene)
        b = scene.physics.bind(scene.wall.body)
        local = (world - b.xpos) @ b.xmat.reshape(3, 3)
        inside = np.all((local >= lo - BODY_BOX_MARGIN_M) & (local <= hi + BODY_BOX_MARGIN_M), axis=-1)
        labels[inside & (labels == 0)] = len(people) + 1
    return labels


def wall_box(scene) -> tuple[np.ndarray, np.ndarray]:
    """The wall body's geoms' bounding box in its own frame (they are boxes, not rotated in it)."""
    m = scene.physics.model
    body_id = m.name2id(scene.wall.body.full_identifier, "body")  # a mocap body: bind() has no element_id
    mine = np.asarray(m.geom_bodyid) == body_id
    pos, size = np.asarray(m.geom_pos)[mine], np.asarray(m.geom_size)[mine]
    return (pos - size).min(axis=0), (pos + size).max(axis=0)


def pixel_rays(K: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W, 3) float32 rays (x/z, y/z, 1) through the pixel centres (the pixel-centre convention)."""
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    return rays.astype(np.float32)


def camera_motion(cam_mid: Rigid, cam_then: Rigid, body_mid: Rigid | None = None,
                  body_then: Rigid | None = None) -> np.ndarray:
    """4×4 map from mid-exposure camera coordinates to the camera coordinates of another instant, of a point fixed
    in the world (no body) or riding on a body that moved from body_mid to body_then."""
    # body_then comes with body_mid
    world = np.eye(4) if body_mid is None else \
        body_then.matrix() @ np.linalg.inv(body_mid.matrix())  # type: ignore[union-attr]
    return np.linalg.inv(cam_then.matrix()) @ world @ cam_mid.matrix()


def _project(points: np.ndarray, T: np.ndarray, K: np.ndarray) -> np.ndarray:
    """(…, 2) float32 pixels of (…, 3) camera points moved by the 4×4 T; behind the camera: NaN. Written out per
    component: a matmul on (H, W, 3) arrays is 5× slower here."""
    X, Y, Z = points[..., 0], points[..., 1], points[..., 2]
    R, t = T[:3, :3].astype(np.float32), T[:3, 3].astype(np.float32)
    x, y, z = (R[i, 0] * X + R[i, 1] * Y + R[i, 2] * Z + t[i] for i in range(3))
    z[z <= 1e-6] = np.nan
    out = np.empty((*z.shape, 2), np.float32)
    out[..., 0] = np.float32(K[0, 0]) * x / z + np.float32(K[0, 2])
    out[..., 1] = np.float32(K[1, 1]) * y / z + np.float32(K[1, 2])
    return out


def motion_paths(points: np.ndarray, labels: np.ndarray, K: np.ndarray, starts: list[np.ndarray],
                 ends: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Start and end pixels (H, W, 2) of each pixel's point: label 0 is the static world, label k ≥ 1 the k-th
    moving body; starts[k] / ends[k] are the label's `camera_motion` maps to the exposure's start and end."""
    u_start, u_end = _project(points, starts[0], K), _project(points, ends[0], K)
    for k in range(1, len(starts)):
        mine = labels == k
        rows, cols = np.flatnonzero(mine.any(axis=1)), np.flatnonzero(mine.any(axis=0))
        if rows.size == 0:
            continue
        box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))  # the body's pixels' bounding box
        where = mine[box][..., None]
        np.copyto(u_start[box], _project(points[box], starts[k], K), where=where)
        np.copyto(u_end[box], _project(points[box], ends[k], K), where=where)
    return u_start, u_end


def displacement(u_start: np.ndarray, u_end: np.ndarray, shape: tuple[int, int], stride: int = 1) -> np.ndarray:
    """(H, W, 2) float32 image motion over the exposure, from paths found at pixels (stride·i, stride·j) and
    interpolated to the image's `shape` (pixel x reads the grid at x / stride); a path with an unknown end (a point
    behind the camera) 0."""
    ok = np.all(np.isfinite(u_start) & np.isfinite(u_end), axis=-1, keepdims=True)
    v = np.where(ok, u_end - u_start, np.float32(0.0)).astype(np.float32)
    if stride > 1:
        xs, ys = np.meshgrid(np.arange(shape[1], dtype=np.float32) / stride,
                             np.arange(shape[0], dtype=np.float32) / stride)
        # float32 in, float32 out (OpenCV's stubs widen the dtype)
        v = cv2.remap(v, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)  # type: ignore[assignment]
    return v


def taps_for(v: np.ndarray, most: int = FIELD_MAX_TAPS) -> int:
    """Taps along the paths so that consecutive ones are ≤ BLUR_STEP_PX apart on the longest, at most `most` (the
    sensor's blur_max_samples: the reference's cap on its renders)."""
    longest = math.sqrt(float((v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]).max())) if v.size else 0.0
    return int(np.clip(math.ceil(longest / BLUR_STEP_PX), 1, min(most, FIELD_MAX_TAPS)))


def blur_along_paths(linear: np.ndarray, v: np.ndarray, taps: int) -> np.ndarray:
    """The mean over the exposure of the mid-exposure image `linear` (H, W, 3 float32) gathered along each pixel's
    path x + s·v, s ∈ [−½, ½] (v: `displacement`), at s = (j + ½) / taps − ½, as the reference places its sub-frames.
    Each tap is one bilinear remap of the image itself (taps of taps would add the interpolation's own blur once per
    pass)."""
    h, w = linear.shape[:2]
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    vx, vy = np.ascontiguousarray(v[..., 0]), np.ascontiguousarray(v[..., 1])
    out = np.zeros_like(linear)
    for j in range(taps):
        s = np.float32((j + 0.5) / taps - 0.5)
        cv2.add(out, cv2.remap(linear, xs - s * vx, ys - s * vy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
                dst=out)
    out /= np.float32(taps)
    return out


def exposure_motion_px(scene, K: np.ndarray, people: bool, exposure_s: float, size: tuple[int, int]) -> float:
    """Largest image motion during the exposure (the last `exposure_s` s of `scene`) of the target centre and the
    people (people: those shown), of the points within BLUR_PROBE_MARGIN of the frame (size: W, H): what sets how
    finely the exposure is sampled (`SensorModel.samples_for_motion`)."""
    now = _probe_points_px(scene, K, people)
    with scene.rewound(exposure_s):
        then = _probe_points_px(scene, K, people)
    d = np.linalg.norm(now - then, axis=1)
    margin = BLUR_PROBE_MARGIN * np.array(size)
    inside = np.all((now > -margin) & (now < list(size) + margin), axis=1)
    d = d[inside & np.isfinite(d)]
    return float(d.max()) if d.size else 0.0


def _probe_points_px(scene, K: np.ndarray, people: bool) -> np.ndarray:
    pts = [scene.target_center_world()]
    for pos, R in (scene.people_poses() if people else []):
        pts += [pos + R @ np.array([0.0, 0.0, z]) for z in PERSON_PROBE_HEIGHTS]
    position, R_cv = scene.camera_pose_cv()
    return project(K, CameraPose(R_cv, position), np.array(pts))


def combine_subframes(full: np.ndarray, small: list[np.ndarray], mid: int) -> np.ndarray:
    """The mean of n sub-frame renders (H, W, 3 linear float32) from n small renders of them (`small`, each h×w×3, the
    same view at 1/scale the size) and a full-size render of the `mid`-th (`full`): the small ones' mean enlarged
    (bilinear, pixel centres aligned), plus α × the middle one's fine detail, `full` − its small render enlarged.

    α says how much of that detail the exposure keeps: 1 where the sub-frames agree (what stands still is exactly
    `full`, as every sub-frame is then), 1/n where the image moves by more than 2·BLUR_STEP_PX over the exposure (as if
    every other sub-frame had lost its detail: the blur along the motion removes most of it), and a linear ramp from
    BLUR_STEP_PX (where the sub-frames would begin) in between. How far the image moves is the small renders' largest
    difference from the middle one over the luma gradient there (the motion across the edge, which is what blurs
    it, in full-size pixels; the farthest sub-frame is about half the exposure's path away), both averaged over 3×3
    small pixels. An edge along the motion changes little between sub-frames and keeps its detail. The result is
    clipped to [0, 1], the range of every render's light."""
    n, (h, w), (H, W) = len(small), small[0].shape[:2], full.shape[:2]
    mean = small[0].copy()
    for s in small[1:]:
        cv2.add(mean, s, dst=mean)
    mean *= np.float32(1.0 / n)
    out = cv2.resize(mean, (W, H), interpolation=cv2.INTER_LINEAR)
    detail = cv2.subtract(full, cv2.resize(small[mid], (W, H), interpolation=cv2.INTER_LINEAR))
    luma = [cv2.transform(s, LUMA.reshape(1, 3)) for s in small]
    gx = cv2.Sobel(luma[mid], cv2.CV_32F, 1, 0, ksize=3, scale=0.125)  # linear light per small pixel
    gy = cv2.Sobel(luma[mid], cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    grad = cv2.blur(cv2.magnitude(gx, gy), (3, 3))
    change = np.zeros((h, w), np.float32)
    for k, lum in enumerate(luma):
        if k != mid:
            cv2.max(change, cv2.absdiff(lum, luma[mid]), dst=change)
    path = cv2.blur(change, (3, 3)) / np.maximum(grad, np.float32(GRADIENT_FLOOR)) * np.float32(2.0 * W / w)  # full-size px
    ramp = np.clip((path - BLUR_STEP_PX) / BLUR_STEP_PX, 0.0, 1.0)
    alpha = cv2.resize(np.float32(1.0) - np.float32(1.0 - 1.0 / n) * ramp, (W, H), interpolation=cv2.INTER_LINEAR)
    cv2.multiply(detail, cv2.merge([alpha, alpha, alpha]), dst=detail)
    cv2.add(out, detail, dst=out)
    return np.clip(out, 0.0, 1.0, out=out)  # the detail of a thin line the small renders miss can overshoot: light is
    # in [0, 1], as every sub-frame's is
