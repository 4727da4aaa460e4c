"""The sequence: the ROI chosen at frame 0, the frames (picture, person, lens, sensor) and their exact ground truth
and occlusion (`make_natural_sequence`)."""

from __future__ import annotations

import math
import time
import zlib
from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.bench.natural.person import Body, _lookalike_cloth, _person, make_body, make_hand
from hvs_sim.bench.natural.picture import MOTIONS, _apply, _blur_samples, _path, _picture, _warp
from hvs_sim.bench.natural.sources import (
    ALL_KINDS,
    DISTORTION_FOVY_DEG,
    FPS,
    MIN_SIZE,
    NATURAL_SOURCES,
    PERSON_STREAM,
    ROI_STREAM,
    _rng,
    _u,
)
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.render.camera import intrinsics
from hvs_sim.scene.textures import trackability
from hvs_sim.sensor import (
    REALISTIC_PRESET,
    SensorState,
    distort_points,
    distortion_maps,
    encode,
    light_scale,
    sensor_preset,
    undistort_points,
)
from hvs_sim.tracking.frames import roi_center, roi_corners

# ---------------------------------------------------------------------------------------------------------------------
# The ROI
# ---------------------------------------------------------------------------------------------------------------------

ROI_WIDTH_PX = (90, 160)
ROI_ASPECT = (0.65, 0.85)  # height / width
ROI_SEARCH_PX = 72  # candidate ROI centres within this of the view centre
ROI_SEARCH_STEP_PX = 12
ROI_KEEP = 0.6  # pick among candidates at least this fraction as trackable as the best
ROI_TEXTURED = 1e-4  # trackability (texture_measure) of a well-textured patch: any candidate above it may be picked


# ---------------------------------------------------------------------------------------------------------------------
# The sequence
# ---------------------------------------------------------------------------------------------------------------------


@dataclass
class NaturalSequence:
    """Frames and exact ground truth; duck-types `bench.sequences.Sequence` for `bench.track.run_tracker`."""

    name: str
    source: str
    kind: str
    seed: int
    camera: str
    frames: np.ndarray  # (N, H, W, 3) uint8 RGB
    homographies: np.ndarray  # (N, 3, 3) pinhole image from picture, at each frame time (end of exposure)
    anchor: np.ndarray  # (2,) the ROI centre of frame 0 on the picture
    occlusion: np.ndarray  # (N,) share of the target ROI polygon covered by the person at the frame time
    roi: tuple[int, int, int, int]
    K: np.ndarray | None = None
    distortion: tuple[float, ...] = ()
    blur_samples: np.ndarray | None = None  # (N,) sub-frame warps of the picture (diagnostics)
    seconds: float = 0.0  # generation time

    @property
    def gt_track(self) -> np.ndarray:
        """(N, 2) true image position of the ROI centre chosen at frame 0 (pixel centres at integers)."""
        p = self.homographies @ np.append(self.anchor, 1.0)
        uv = p[:, :2] / p[:, 2:]
        return distort_points(self.K, self.distortion, uv) if self.distortion else uv


def _check(source: str, kind: str, seed, n_frames, size) -> tuple[int, int]:
    if source not in NATURAL_SOURCES:
        raise choice_error("natural source", source, NATURAL_SOURCES)
    if kind not in ALL_KINDS:
        raise choice_error("natural kind", kind, ALL_KINDS)
    for what, v, low in (("seed", seed, 0), ("n_frames", n_frames, 2)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
            raise ConfigError(f"natural sequence {what} must be an integer >= {low}, got {v!r}")
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        raise ConfigError(f"natural sequence size must be (width, height), got {size!r}") from None
    if not (MIN_SIZE[0] <= w <= 4096 and MIN_SIZE[1] <= h <= 4096):
        raise ConfigError(f"natural sequence size must be at least {MIN_SIZE} and at most 4096, got {size!r}")
    return w, h


def _choose_roi(rng: np.random.Generator, frame0: np.ndarray) -> tuple[int, int, int, int]:
    """A ROI near the view centre, on texture: a seeded pick among the well-textured candidates (or, where the view
    has none, those at least ROI_KEEP × as trackable as the best)."""
    h, w = frame0.shape[:2]
    rw = int(rng.integers(ROI_WIDTH_PX[0], ROI_WIDTH_PX[1] + 1))
    rh = round(rw * _u(rng, ROI_ASPECT))
    offs = np.arange(-ROI_SEARCH_PX, ROI_SEARCH_PX + 1, ROI_SEARCH_STEP_PX)
    cands, scores = [], []
    for oy in offs:
        for ox in offs:
            x = round((w - rw) / 2 + ox)
            y = round((h - rh) / 2 + oy)
            cands.append((x, y, rw, rh))
            scores.append(trackability(frame0[y:y + rh, x:x + rw]))
    scores = np.array(scores)
    keep = np.flatnonzero(scores >= min(ROI_KEEP * scores.max(), ROI_TEXTURED))
    return cands[int(keep[rng.integers(len(keep))])]


def _polygon_mask(poly: np.ndarray, view: tuple[int, int]) -> np.ndarray:
    m = np.zeros((view[1], view[0]), np.uint8)
    cv2.fillPoly(m, [np.round(poly * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
    return m.astype(bool)


def _roi_outline(roi, per_edge: int) -> np.ndarray:
    """Points along the ROI's outer pixel edges (dense enough to follow a lens-curved outline)."""
    c = roi_corners(roi)
    u = np.arange(per_edge)[:, None] / per_edge
    return np.concatenate([c[i] + u * (c[(i + 1) % 4] - c[i]) for i in range(4)])


def _occlusion(body: Body, A: np.ndarray, outline: np.ndarray, view: tuple[int, int], K, distortion, maps) -> float:
    """Share of the target's outline (pinhole image points) covered by the person's alpha at the frame time."""
    if maps is None:
        box = body.box(A, view)
        inside = _polygon_mask(outline, view)
        if box is None or not inside.any():
            return 0.0
        x0, y0, x1, y1 = box
        alpha = np.zeros(inside.shape, np.float32)
        alpha[y0:y1, x0:x1] = body.render(A, box)[..., 3]
    else:  # through the lens: the whole view's alpha, distorted like the frame, over the distorted outline
        alpha = cv2.remap(np.ascontiguousarray(body.render(A, (0, 0, *view))[..., 3]), *maps, cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REPLICATE)
        inside = _polygon_mask(distort_points(K, distortion, outline), view)
        if not inside.any():
            return 0.0
    return float(np.clip(alpha[inside].mean(), 0.0, 1.0))


def make_natural_sequence(source: str, kind: str, seed: int, n_frames: int = 150, camera: str = REALISTIC_PRESET,
                          size=(640, 480), motion: str = "hand") -> NaturalSequence:
    """A seeded hand-held sequence of a planar picture, optionally with a person crossing, pausing or standing beside.

    source: one of NATURAL_SOURCES; kind: one of ALL_KINDS; camera: a `sensor` preset (`ideal`
    gives clean frames); motion: one of MOTIONS. Returns a `NaturalSequence` (frames, roi, gt_track, occlusion, name).
    """
    start = time.perf_counter()
    view = _check(source, kind, seed, n_frames, size)
    if motion not in MOTIONS:
        raise choice_error("natural motion", motion, tuple(MOTIONS))
    seed = int(seed)
    model = sensor_preset(camera)
    if model.exposure_ms > 1000.0 / FPS:
        raise ConfigError(f"camera {camera!r}: exposure {model.exposure_ms} ms is longer than a frame at {FPS:g} fps")
    w, h = view
    times = np.arange(n_frames) / FPS
    picture = _picture(source, seed, view)
    path = _path(source, seed, picture.shape[:2], view, times, motion)
    K = intrinsics(w, h, DISTORTION_FOVY_DEG) if model.distortion else None
    maps = distortion_maps(K, model.distortion, w, h) if model.distortion else None

    def lens(img: np.ndarray, interp=cv2.INTER_LINEAR) -> np.ndarray:
        return img if maps is None else cv2.remap(img, *maps, interp, borderMode=cv2.BORDER_REPLICATE)

    H0 = path.homography(0.0)
    H0_inv = np.linalg.inv(H0)
    roi = _choose_roi(_rng(source, seed, ROI_STREAM), encode(lens(_warp(picture, H0, view))))
    centre0 = roi_center(roi)[None]
    anchor = _apply(H0_inv, undistort_points(K, model.distortion, centre0) if maps is not None else centre0)[0]
    outline = _apply(H0_inv, undistort_points(K, model.distortion, _roi_outline(roi, 8))
                     if maps is not None else roi_corners(roi))

    body, person = None, None
    if kind != "clear":
        prng = _rng(source, seed, PERSON_STREAM, zlib.crc32(kind.encode()))
        person, width = _person(kind, prng, roi, view, n_frames / FPS)
        if kind == "hand":
            body = make_hand(prng, width)
        elif kind == "lookalike":
            body = make_body(prng, width, h, cloth=_lookalike_cloth(picture, anchor, roi, path.zoom, prng))
        else:
            body = make_body(prng, width, h)

    sensor_seed = zlib.crc32(f"{source}:{seed}".encode()) & 0x7FFFFFFF
    state = None if model.is_ideal else SensorState(model, sensor_seed, (h, w))
    probes = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1], [(w - 1) / 2, (h - 1) / 2]], float)
    exposure = model.exposure_ms * 1e-3

    def person_pose(t: float):
        """The person's image pose at t: its room position seen through the moved camera, turned with its roll."""
        pose = person.pose(t)
        if pose is None:
            return None
        q = _apply(path.homography(t) @ H0_inv, np.array([pose[:2]]))[0]
        return float(q[0]), float(q[1]), pose[2] + path.roll(t)

    frames = np.empty((n_frames, h, w, 3), np.uint8)
    Hs = np.empty((n_frames, 3, 3))
    occ = np.zeros(n_frames)
    nblur = np.ones(n_frames, np.int32)
    for k, t in enumerate(times):
        t = float(t)
        H = path.homography(t)
        Hs[k] = H
        # the picture, averaged over the exposure (the frame time is its end)
        smear = 0.0  # image motion over the exposure (px)
        if exposure > 0:
            smear = float(np.abs(_apply(H @ np.linalg.inv(path.homography(t - exposure)), probes) - probes).max())
        offsets = model.exposure_offsets(_blur_samples(smear, model))
        nblur[k] = len(offsets)
        linear = None
        for dt in offsets:
            img = _warp(picture, path.homography(t - float(dt)), view)
            weight = (light_scale(model, sensor_seed, t - dt) if model.lights_change else 1.0) / len(offsets)
            if weight != 1.0:
                img *= np.float32(weight)
            linear = img if linear is None else np.add(linear, img, out=linear)
        if body is not None:
            # the person, averaged over its own sub-frame instants; composited over the averaged picture (exact
            # when either layer holds still during the exposure, and the picture's motion in 8 ms is < 1 px)
            now = person_pose(t)
            before = person_pose(t - exposure) if exposure > 0 else None
            pmotion = 0.0 if now is None or before is None else math.hypot(now[0] - before[0], now[1] - before[1])
            p_offsets = model.exposure_offsets(_blur_samples(pmotion, model))
            placed = []
            for dt in p_offsets:
                pose = person_pose(t - float(dt))
                A = None if pose is None else body.transform(*pose)
                box = None if A is None else body.box(A, view)
                if box is not None:
                    placed.append((A, box))
            if placed:
                x0, y0 = min(p[1][0] for p in placed), min(p[1][1] for p in placed)
                x1, y1 = max(p[1][2] for p in placed), max(p[1][3] for p in placed)
                layer = body.render(placed[0][0], (x0, y0, x1, y1))
                for A, _ in placed[1:]:
                    layer += body.render(A, (x0, y0, x1, y1))
                # the light's change over one exposure is negligible (dimming over seconds): one factor
                light = light_scale(model, sensor_seed, t - exposure / 2) if model.lights_change else 1.0
                n = np.float32(len(p_offsets))
                under = linear[y0:y1, x0:x1]
                under *= 1.0 - layer[..., 3:] / n
                under += layer[..., :3] * np.float32(light / n)
            occ[k] = 0.0 if now is None else _occlusion(body, body.transform(*now), _apply(H, outline), view, K,
                                                         model.distortion, maps)
        linear = lens(linear)
        frames[k] = encode(linear) if state is None else state.capture(linear, k, t, 1.0 / FPS)
    name = (f"{source}/{kind}/s{seed}" + ("" if camera == REALISTIC_PRESET else f"/{camera}")
            + ("" if motion == "hand" else f"/{motion}"))
    return NaturalSequence(name=name, source=source, kind=kind, seed=seed, camera=camera, frames=frames,
                           homographies=Hs, anchor=anchor, occlusion=occ, roi=roi, K=K,
                           distortion=model.distortion, blur_samples=nblur, seconds=time.perf_counter() - start)
