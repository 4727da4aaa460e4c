"""The picture in linear light and the hand-held camera: a seeded path of picture-to-image homographies (drift,
tremor, roll, zoom, tilt), the supersampled warp and the motion-blur sample count."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from hvs_sim.bench.natural.sources import PATH_STREAM, PICTURE_STREAM, _rng, _u
from hvs_sim.scene.textures import PHOTO_SOURCES, _photo_source, natural_texture
from hvs_sim.sensor import SensorModel, decode

# ---------------------------------------------------------------------------------------------------------------------
# The picture and the hand-held camera
# ---------------------------------------------------------------------------------------------------------------------

VIEW_COVERAGE = (0.6, 0.78)  # the view spans this fraction of the picture's width at frame 0
MAX_HEIGHT_COVERAGE = 0.85  # ...and at most this of its height (3:2 photos seen through a 4:3 view)
START_OFFSET = 0.5  # the view centre starts within this fraction of the free margin from the picture centre
FIT_ZOOM_STEP = 1.04  # zoom in by this until the view stays on the picture for the whole path
FIT_TRIES = 30
EDGE_GUARD_PX = 2.0  # picture pixels kept free of the view's border (bilinear reads one beyond)
GREY_TINT = 0.05  # grey photos get a warm or cool cast per seed (a print under a lamp)
SUPERSAMPLE = 2  # warp at 2× then area-average: every pixel integrates its footprint

DRIFT_HZ = (0.08, 0.3)  # slow drift of the hand: 3 components per axis
DRIFT_PX = 14.0  # image px per drift component (≤ 2.6 px/frame per axis, typically 0.7)
TREMOR_HZ = (1.0, 10.0)  # physiological tremor: 5 components per axis
TREMOR_PX_HZ = 2.0  # tremor amplitude × frequency (px·Hz): 2 px at 1 Hz, 0.2 px at 10 Hz
ROLL0_DEG = 2.0  # the phone is not held level
ROLL_DRIFT_DEG = 0.6  # per drift component: a few degrees of roll over a sequence
ROLL_TREMOR_DEG_HZ = 0.15
SCALE_DRIFT = 0.006  # per drift component: ±3.6 % at most (the hand moves towards and away)
PERSPECTIVE = 1e-4  # 1/px: at the image edge (320 px) a 3 % keystone
PERSPECTIVE_DRIFT = 0.3  # of PERSPECTIVE, per drift component
# how the hand moves (`motion`): "hand" as above; "tilt" a phone turned out of the picture's plane and brought
# closer and further: ×3.5 the perspective (up to ~4e-4/px, 10–13° of tilt at the view's 580 px focal length) and
# ×5 the scale drift (±18 % zoom over a sequence)
MOTIONS = {"hand": (1.0, 1.0), "tilt": (3.5, 5.0)}  # name → (perspective gain, scale-drift gain)

BLUR_STEP_PX = 1.5  # at most this image motion between two sub-frame warps (as sensor.BLUR_STEP_PX)
MIN_BLUR_SAMPLES = 3  # when anything moves visibly during the exposure, at least this many
MAX_BLUR_SAMPLES = 5
BLUR_MIN_MOTION_PX = 0.3  # below this, the exposure's smear is invisible: one warp


def _picture(source: str, seed: int, view: tuple[int, int]) -> np.ndarray:
    """The picture in linear light (float32 RGB): a whole photo, or a procedural texture at ~1 px per view px."""
    rng = _rng(source, seed, PICTURE_STREAM)
    if source in PHOTO_SOURCES:
        img = _photo_source(source)
        if img.ndim == 2:
            warmth = rng.uniform(-GREY_TINT, GREY_TINT)
            tint = np.array([1 + warmth, 1.0, 1 - warmth], np.float32)
            img = np.clip(img.astype(np.float32)[..., None] * tint + 0.5, 0, 255).astype(np.uint8)
    else:
        cov = _u(rng, VIEW_COVERAGE)
        w, h = view
        img = natural_texture(source, round(w / cov), round(h / cov), seed)
    return decode(np.ascontiguousarray(img))


def _waves(rng: np.random.Generator, n: int, hz, amp_scale: float, per_hz: bool = False):
    """n sinusoids: (amplitudes, frequencies, phases); per_hz: amplitude falls as 1/f (tremor)."""
    f = rng.uniform(*hz, n)
    a = amp_scale * rng.uniform(0.5 if not per_hz else 0.3, 1.0, n)
    if per_hz:
        a = a / f
    return a, f, rng.uniform(0, 2 * np.pi, n)


def _wave_sum(w, t: float) -> float:
    """Σ a·(sin(2πft + φ) − sin φ): zero at t = 0, so frame 0 is the path's base pose."""
    a, f, ph = w
    return float(np.sum(a * (np.sin(2 * np.pi * f * t + ph) - np.sin(ph))))


@dataclass(frozen=True)
class HandHeldPath:
    """Image-from-picture homography of a phone held in the hand, as a function of time.

    H(t) = T(c) · P(t) · T(d(t)) · s(t) R(θ(t)) · T(−p0): the picture point p0 sits at the image centre
    c at frame 0; d is the drift + tremor of the view (image px), θ the roll, s the zoom, and P a small
    projective tilt about the optical axis (the image centre).
    """

    centre: tuple[float, float]
    p0: tuple[float, float]
    zoom: float
    roll0: float
    waves: dict = field(repr=False)
    perspective: float = PERSPECTIVE  # 1/px per unit of the tilt waves (MOTIONS)

    def homography(self, t: float) -> np.ndarray:
        w = self.waves
        dx = _wave_sum(w["x"], t) + _wave_sum(w["tx"], t)
        dy = _wave_sum(w["y"], t) + _wave_sum(w["ty"], t)
        th = self.roll0 + math.radians(_wave_sum(w["roll"], t) + _wave_sum(w["troll"], t))
        s = self.zoom * (1.0 + _wave_sum(w["scale"], t))
        gx = self.perspective * (w["g0"][0] + _wave_sum(w["gx"], t))
        gy = self.perspective * (w["g0"][1] + _wave_sum(w["gy"], t))
        c, sn = s * math.cos(th), s * math.sin(th)
        cx, cy = self.centre
        A = np.array([[c, -sn, dx - c * self.p0[0] + sn * self.p0[1]],
                      [sn, c, dy - sn * self.p0[0] - c * self.p0[1]],
                      [0.0, 0.0, 1.0]])
        P = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [gx, gy, 1.0]])
        return np.array([[1.0, 0.0, cx], [0.0, 1.0, cy], [0.0, 0.0, 1.0]]) @ P @ A

    def roll(self, t: float) -> float:
        """Roll (rad) relative to frame 0: a body near the lens turns with the camera."""
        w = self.waves
        return math.radians(_wave_sum(w["roll"], t) + _wave_sum(w["troll"], t))


def _path(source: str, seed: int, picture_hw: tuple[int, int], view: tuple[int, int], times: np.ndarray,
          motion: str = "hand") -> HandHeldPath:
    """A seeded hand-held path whose view stays on the picture for the whole sequence (zooming in if needed); the
    `motion`'s gains scale its tilt and zoom waves (one seed: one path shape, whatever the motion)."""
    tilt_gain, zoom_gain = MOTIONS[motion]
    rng = _rng(source, seed, PATH_STREAM)
    ph, pw = picture_hw
    w, h = view
    cov = min(_u(rng, VIEW_COVERAGE), MAX_HEIGHT_COVERAGE * (w / h) * (ph / pw))
    zoom = w / (cov * pw)
    waves = {
        "x": _waves(rng, 3, DRIFT_HZ, DRIFT_PX), "y": _waves(rng, 3, DRIFT_HZ, DRIFT_PX),
        "tx": _waves(rng, 5, TREMOR_HZ, TREMOR_PX_HZ, True), "ty": _waves(rng, 5, TREMOR_HZ, TREMOR_PX_HZ, True),
        "roll": _waves(rng, 3, DRIFT_HZ, ROLL_DRIFT_DEG), "troll": _waves(rng, 5, TREMOR_HZ, ROLL_TREMOR_DEG_HZ, True),
        "scale": _waves(rng, 3, DRIFT_HZ, SCALE_DRIFT * zoom_gain),
        "gx": _waves(rng, 3, DRIFT_HZ, PERSPECTIVE_DRIFT), "gy": _waves(rng, 3, DRIFT_HZ, PERSPECTIVE_DRIFT),
        "g0": tuple(rng.uniform(-0.5, 0.5, 2)),
    }
    roll0 = math.radians(rng.uniform(-ROLL0_DEG, ROLL0_DEG))
    offset = rng.uniform(-START_OFFSET, START_OFFSET, 2)
    centre = ((w - 1) / 2.0, (h - 1) / 2.0)
    view_corners = np.array([[-0.5, -0.5, 1.0], [w - 0.5, -0.5, 1.0], [w - 0.5, h - 0.5, 1.0], [-0.5, h - 0.5, 1.0]])
    for _ in range(FIT_TRIES):
        margin = np.array([pw - w / zoom, ph - h / zoom]) / 2.0
        p0 = np.array([(pw - 1) / 2.0, (ph - 1) / 2.0]) + offset * np.maximum(margin, 0.0)
        path = HandHeldPath(centre, (float(p0[0]), float(p0[1])), zoom, roll0, waves, PERSPECTIVE * tilt_gain)
        pts = np.concatenate([(np.linalg.inv(path.homography(float(t))) @ view_corners.T).T for t in times])
        pts = pts[:, :2] / pts[:, 2:]
        lo, hi = EDGE_GUARD_PX, np.array([pw - 1, ph - 1]) - EDGE_GUARD_PX
        if np.all(pts >= lo) and np.all(pts <= hi):
            return path
        zoom *= FIT_ZOOM_STEP
    return path  # the last, most zoomed-in try; any sliver outside is mirrored (BORDER_REFLECT_101)


_SS = np.array([[SUPERSAMPLE, 0.0, (SUPERSAMPLE - 1) / 2.0], [0.0, SUPERSAMPLE, (SUPERSAMPLE - 1) / 2.0], [0.0, 0.0, 1.0]])


def _warp(picture: np.ndarray, H: np.ndarray, view: tuple[int, int]) -> np.ndarray:
    """The picture seen through H (pixel centres at integers on both sides), integrated over each pixel."""
    w, h = view
    big = cv2.warpPerspective(picture, _SS @ H, (w * SUPERSAMPLE, h * SUPERSAMPLE), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REFLECT_101)
    return cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)


def _apply(H: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = np.column_stack([pts, np.ones(len(pts))]) @ H.T
    return p[:, :2] / p[:, 2:]


def _blur_samples(motion_px: float, model: SensorModel) -> int:
    """Sub-frame warps for this much image motion over the exposure (1 when the smear is invisible)."""
    if model.exposure_ms <= 0 or motion_px < BLUR_MIN_MOTION_PX:
        return 1
    n = math.ceil(motion_px / BLUR_STEP_PX)
    return int(np.clip(n, MIN_BLUR_SAMPLES, max(1, min(model.blur_max_samples, MAX_BLUR_SAMPLES))))
