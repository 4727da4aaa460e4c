"""`hvs-sim bench track --imagery natural`: trackers on real photographs filmed like a hand-held phone.

The hybrid is judged on held-out real-photo sequences (a portrait, a cat, a cup, a street… moved by
hand, with exposure drift, noise, JPEG and a person crossing or pausing over the target). Rendered
flag walls are not that, so this module builds sequences of the same kind from the ONLY image
sources this project may use: the scikit-learn sample photos (china, flower), the PyWavelets photos
(aero, ascent) and the procedural textures of `hvs_sim.scene.textures`; bodies are drawn from the
procedural fabrics of `hvs_sim.scene.people`. scikit-image's and matplotlib's sample photographs are
the held-out set's kind of data and must never be imported here; nor is `pywt.data.camera`, which is
scikit-image's cameraman (see scene/textures/__init__.py).

A sequence: a planar picture seen through a camera whose picture-to-image homography H_t drifts and
trembles like a phone in the hand (slow drift of a few px per frame, a few degrees of roll, ±3 %
scale, a little perspective, 1–10 Hz tremor). Frames are warped from the picture in LINEAR light at
2× and box-filtered to 1× (each pixel integrates its area: no aliasing), averaged over sub-frame
instants of the preset's exposure (motion blur), composited with a clothed body close to the lens
(blurred by its own motion), optionally lens-distorted, then captured by the preset's camera model
(`SensorState`: auto-exposure, noise, sRGB, JPEG) under its light changes (`light_scale`).

Ground truth: the ROI centre chosen at frame 0 is undistorted, taken onto the picture by H_0⁻¹ and
back into frame t by H_t (then distorted): exact, at the frame time, i.e. at the END of the exposure,
as the simulator's. Presets with lens distortion (webcam) are supported: the frames and the occluder
mask go through `distortion_maps`, the ground truth through `distort_points`.

Every draw is seeded by (source, seed) for the picture, camera path, ROI and sensor, so the kinds of
one (source, seed) are the same shot with and without the person (paired), and by the kind for the
person: the same (source, kind, seed, camera, n_frames, size) gives bit-identical frames.
"""

from __future__ import annotations

import json
import math
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from hvs_sim.bench.pool import collect_jobs, config_json, write_frames_csv
from hvs_sim.camera_model import (
    REALISTIC_PRESET,
    SensorModel,
    SensorState,
    decode,
    distort_points,
    distortion_maps,
    encode,
    light_scale,
    sensor_preset,
    undistort_points,
)
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.outputs import write_atomic
from hvs_sim.render.camera import intrinsics
from hvs_sim.scene.textures import PHOTO_SOURCES, _photo_source, natural_texture, trackability
from hvs_sim.tracking.frames import roi_center, roi_corners

# ---------------------------------------------------------------------------------------------------------------------
# Sources and kinds
# ---------------------------------------------------------------------------------------------------------------------

NATURAL_PHOTOS = ("photo_china", "photo_flower", "photo_aero", "photo_ascent")  # every allowed real photo
# procedural pictures: printed matter and materials, with the self-similar ones (fur, foliage, brick,
# gravel, bark, mosaic) that defeat a global re-detection
NATURAL_PROCEDURAL = ("fur", "foliage", "brick", "gravel", "bark", "poster", "wood", "marble", "mosaic", "corkboard")
NATURAL_SOURCES: tuple[str, ...] = NATURAL_PHOTOS + NATURAL_PROCEDURAL
NATURAL_KINDS = ("clear", "walk_by", "pause", "partial")  # the default set: its figures stay comparable
# harder occluders, asked for by name: a person dressed in the picture's own texture, a hand close to the lens
# (skin, defocused) and a long pause (several seconds hidden while the phone keeps moving)
EXTRA_KINDS = ("lookalike", "hand", "long")
ALL_KINDS = NATURAL_KINDS + EXTRA_KINDS
OCCLUDED_KINDS = ("walk_by", "pause", "partial", *EXTRA_KINDS)
DEFAULT_SEEDS = (500, 501)

FPS = 30.0  # as the simulator's scenarios
T_REF_S = 5.0  # a 150-frame sequence; the person's schedule is compressed for shorter ones
MIN_SIZE = (320, 240)  # the largest ROI (160 px wide) must fit well inside the view
DISTORTION_FOVY_DEG = 45.0  # K for lens distortion: the simulator's default CameraConfig.fovy

# seed streams (rng = default_rng([crc32(source), seed, STREAM, ...]))
PICTURE_STREAM, PATH_STREAM, ROI_STREAM, PERSON_STREAM = 1, 2, 3, 4

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

BLUR_STEP_PX = 1.5  # at most this image motion between two sub-frame warps (as camera_model.BLUR_STEP_PX)
MIN_BLUR_SAMPLES = 3  # when anything moves visibly during the exposure, at least this many
MAX_BLUR_SAMPLES = 5
BLUR_MIN_MOTION_PX = 0.3  # below this, the exposure's smear is invisible: one warp

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
# The person close to the lens (sizes in units of the body's width B: arm to arm)
# ---------------------------------------------------------------------------------------------------------------------

TORSO_HALF = 0.35
TORSO_NECKLINE = (0.12, -0.06)  # (half width, height) where the shoulders leave the neck (y down from the anchor)
TORSO_CORNER = 0.1  # the shoulders slope from the neckline to this round corner at the torso's side
ARM_TOP = 0.02  # the arms hang from just below the shoulder line: their round tops make the deltoids
ARM_HALF = 0.08  # upper arm and sleeve, hanging against the torso
ARM_LENGTH = 1.5  # shoulder to wrist
SHORT_SLEEVE = 0.45
HAND_AXES = (0.075, 0.11)
NECK = (0.085, 0.25)  # half width, height above the shoulder line
HEAD_CENTRE = 0.47  # above the shoulder line
HEAD_AXES = (0.185, 0.245)
HAIR_RISE = 0.05  # hair sits this much higher and wider than the skull
FACE_SHOWN = 0.6  # the person faces the camera (else: the back of the head, all hair)
HAIRLINE = (0.08, 0.16)  # the face's ellipse sits this far below the head's centre: a curved hairline
FACE_AXES = (0.16, 0.22)
TILE_OF_BODY = 0.31  # one fabric tile (TILE_M = 0.154 m of cloth) across a 0.5 m wide body
FABRIC_DRAW = 512
SHADE_EDGE = 0.45  # radiance at a part's silhouette relative to its middle: round bodies darken to the sides
FEATHER_PX = 0.8  # Gaussian feather of the silhouette (a 1–2 px soft edge)
PERSON_LIGHT = (0.5, 1.0)  # a body near the lens stands in its own shadow: the auto-exposure reacts
SPRITE_LENGTH = 2.4  # shoulder to the sprite's bottom, in view heights: always past the frame's bottom
OFF_MARGIN_PX = 80.0  # a person out of view is this far beyond the edge (the camera moves too)
SHOULDER_ABOVE_ROI = (0.1, 0.3)  # shoulder line above the target's top, × B

WALK_FULL_FRAMES = (10, 15)  # frames the crossing body covers the whole target
WALK_CROSS_S = (1.4, 1.8)  # edge in to edge out
WALK_WIDTH_PX = (260, 520)
STEP_HZ = (1.7, 2.1)
BOB = 0.012  # vertical bob of the gait, × B
LEAN_DEG = 1.5
PAUSE_WIDTH_PX = (320, 480)
PAUSE_START = (0.15, 0.28)  # × sequence length
PAUSE_MOVE_S = (0.6, 0.9)  # coming in, going out
PAUSE_STAY_S = (0.7, 1.1)  # standing still; with the last and first steps, covered 90–100 % for ~1–1.5 s
PAUSE_OFFSET = 0.2  # stop within this fraction of the free half-width from dead centre
SWAY_PX = (3.0, 8.0)
SWAY_HZ = (0.3, 0.6)
SWAY_DEG = (0.3, 1.0)
LONG_STAY_S = (2.5, 3.0)  # `long`: standing still over the target while the phone keeps moving
LONG_WIDTH_PX = (260, 340)  # ... and narrower than `pause`'s, so that most of the surroundings stay in view
HAND_STAY_S = (1.8, 2.2)  # `hand`: held over the target for ~2 s
HAND_WIDTH_OF_ROI = (1.4, 1.8)  # the hand's width over the ROI's: it covers the whole target
HAND_DEFOCUS_PX = 5.0  # a hand 10–20 cm from the lens is far out of focus: its edges and skin texture blur
HAND_EDGE_PX = 6.0
LOOKALIKE_CROP = 2.5  # `lookalike`: the clothing is the picture around the target, this many ROI widths across
PARTIAL_WIDTH_PX = (280, 460)
PARTIAL_START = (0.05, 0.12)
PARTIAL_END = (0.82, 0.9)
PARTIAL_MOVE_S = (0.5, 0.8)
PARTIAL_COVER = (0.32, 0.68)  # the share of the target's width the body keeps covered
PARTIAL_HZ = (0.2, 0.45)


def _rng(source: str, seed: int, *stream: int) -> np.random.Generator:
    return np.random.default_rng([zlib.crc32(source.encode()), seed, *stream])


def _u(rng: np.random.Generator, lo_hi) -> float:
    return float(rng.uniform(*lo_hi))


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


# ---------------------------------------------------------------------------------------------------------------------
# The body: a 2-D figure with textured clothes, skin and hair, shaded round, feathered edge
# ---------------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Body:
    """A person's image as a sprite: premultiplied linear RGB + alpha, and the shoulder-line centre (anchor)."""

    rgba: np.ndarray  # (h, w, 4) float32: RGB × alpha, alpha
    anchor: tuple[float, float]
    width_px: float  # B: arm to arm

    def transform(self, x: float, y: float, angle: float) -> np.ndarray:
        """2×3 view-from-sprite affine that puts the anchor at (x, y), turned by `angle` (rad)."""
        c, s = math.cos(angle), math.sin(angle)
        ax, ay = self.anchor
        return np.array([[c, -s, x - (c * ax - s * ay)], [s, c, y - (s * ax + c * ay)]])

    def box(self, A: np.ndarray, view: tuple[int, int]) -> tuple[int, int, int, int] | None:
        """The view pixels (x0, y0, x1, y1) the placed sprite can touch; None if it is out of view."""
        h, w = self.rgba.shape[:2]
        pts = np.array([[-1, -1], [w, -1], [w, h], [-1, h]], float) @ A[:, :2].T + A[:, 2]
        x0, y0 = np.maximum(np.floor(pts.min(0)).astype(int), 0)
        x1, y1 = np.minimum(np.ceil(pts.max(0)).astype(int) + 1, view)
        return None if x0 >= x1 or y0 >= y1 else (int(x0), int(y0), int(x1), int(y1))

    def render(self, A: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
        """The placed sprite over the view window `box` (premultiplied RGB + alpha)."""
        x0, y0, x1, y1 = box
        At = A.copy()
        At[:, 2] -= (x0, y0)
        return cv2.warpAffine(self.rgba, At, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _tile(tex: np.ndarray, tile_px: int, shape: tuple[int, int]) -> np.ndarray:
    """A seamless texture resized to tile_px and repeated over `shape`, in linear light."""
    t = cv2.resize(tex, (tile_px, tile_px), interpolation=cv2.INTER_AREA)
    h, w = shape
    reps = (h // tile_px + 1, w // tile_px + 1, 1)
    return decode(np.ascontiguousarray(np.tile(t, reps)[:h, :w]))


def _rounded_rect(x0: float, y0: float, x1: float, y1: float, r: float) -> np.ndarray:
    """Outline of a rounded rectangle (corner radius r), 1/16-px fixed point for cv2.fillPoly."""
    pts = []
    for cx, cy, a0 in ((x1 - r, y0 + r, 270), (x1 - r, y1 - r, 0), (x0 + r, y1 - r, 90), (x0 + r, y0 + r, 180)):
        ang = np.radians(np.arange(a0, a0 + 91, 10))
        pts.append(np.column_stack([cx + r * np.cos(ang), cy + r * np.sin(ang)]))
    return np.round(np.concatenate(pts) * 16).astype(np.int32)


def _torso_outline(ax: float, ay: float, B: float, bottom: float) -> np.ndarray:
    """Torso with sloped shoulders (neckline → rounded shoulder corner → straight sides), fixed point."""
    nx, ny = TORSO_NECKLINE
    r = TORSO_CORNER
    cx, cy = TORSO_HALF - r, -0.02 + r  # corner centre, right side, in units of B
    ang = np.radians(np.arange(270, 361, 10))
    right = np.concatenate([[[nx, ny]], np.column_stack([cx + r * np.cos(ang), cy + r * np.sin(ang)])])
    right = np.concatenate([right * B + (ax, ay), [[ax + TORSO_HALF * B, bottom]]])
    left = right[::-1] * (-1, 1) + (2 * ax, 0)
    return np.round(np.concatenate([right, left]) * 16).astype(np.int32)


def _poly_mask(shape, poly: np.ndarray) -> np.ndarray:
    m = np.zeros(shape, np.uint8)
    cv2.fillPoly(m, [poly], 255, cv2.LINE_AA, shift=4)
    return m.astype(np.float32) / 255.0


def _ellipse_mask(shape, centre, axes) -> np.ndarray:
    m = np.zeros(shape, np.uint8)
    c = (round(centre[0] * 16), round(centre[1] * 16))
    a = (round(axes[0] * 16), round(axes[1] * 16))
    cv2.ellipse(m, c, a, 0, 0, 360, 255, -1, cv2.LINE_AA, shift=4)
    return m.astype(np.float32) / 255.0


def _round_shade(mask: np.ndarray, half_width: float) -> np.ndarray:
    """1 in a part's middle, SHADE_EDGE at its silhouette: a rounded body lit from the front."""
    d = cv2.distanceTransform((mask > 0.5).astype(np.uint8), cv2.DIST_L2, 5)
    return SHADE_EDGE + (1.0 - SHADE_EDGE) * np.sqrt(np.clip(d / max(half_width, 1.0), 0.0, 1.0))


def _lookalike_cloth(picture: np.ndarray, anchor: np.ndarray, roi, zoom: float,
                     rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """A piece of the picture beside the target (LOOKALIKE_CROP ROI widths across, its centre that far from the
    target's in a seeded direction, sRGB) and its side in view pixels: clothing of the scene's own texture at the
    scene's scale (a brick-print shirt before a brick wall), not a copy of the target itself."""
    side = max(8, round(LOOKALIKE_CROP * roi[2] / zoom))  # picture px
    ph, pw = picture.shape[:2]
    heading = rng.uniform(0, 2 * np.pi)
    cx, cy = anchor + side * np.array([np.cos(heading), np.sin(heading)])
    x0 = int(np.clip(round(cx - side / 2), 0, max(pw - side, 0)))
    y0 = int(np.clip(round(cy - side / 2), 0, max(ph - side, 0)))
    crop = encode(np.ascontiguousarray(picture[y0:y0 + side, x0:x0 + side]))
    return crop, max(16, round(side * zoom))


def make_hand(rng: np.random.Generator, width_px: float) -> Body:
    """An open hand close to the lens: palm, four fingers and a thumb in a sampled skin tone, defocused (its
    texture and edges blurred by HAND_DEFOCUS_PX and HAND_EDGE_PX); the anchor is the palm's centre."""
    from hvs_sim.scene.people import Outfit, skin_texture

    outfit = Outfit.sample(rng)
    B = float(width_px)
    pad = 3 * HAND_EDGE_PX
    w, h = math.ceil(B + 2 * pad), math.ceil(1.5 * B + 2 * pad)
    ax, ay = w / 2.0, pad + 0.95 * B
    shape = (h, w)
    mask = _ellipse_mask(shape, (ax, ay), (0.42 * B, 0.45 * B))  # the palm
    for k in range(4):  # fingers, fanned a little
        x = ax + (k - 1.5) * 0.2 * B
        top = ay - (0.85 + 0.08 * (1.5 - abs(k - 1.5))) * B
        mask = np.maximum(mask, _poly_mask(shape, _rounded_rect(x - 0.085 * B, top, x + 0.085 * B, ay, 0.085 * B)))
    side = 1 if rng.uniform() < 0.5 else -1
    thumb_x = ax + side * 0.45 * B
    mask = np.maximum(mask, _poly_mask(shape, _rounded_rect(thumb_x - 0.1 * B, ay - 0.35 * B, thumb_x + 0.1 * B,
                                                            ay + 0.15 * B, 0.1 * B)))
    skin = _tile(skin_texture(outfit.skin, int(rng.integers(2 ** 31))), max(16, round(0.6 * B)), shape)
    skin = cv2.GaussianBlur(skin, (0, 0), HAND_DEFOCUS_PX)
    shaded = skin * (_round_shade(mask, 0.5 * B) * np.float32(_u(rng, PERSON_LIGHT)))[..., None]
    alpha = cv2.GaussianBlur(mask, (0, 0), HAND_EDGE_PX)
    rgba = np.dstack([shaded * alpha[..., None], alpha]).astype(np.float32)
    return Body(rgba, (ax, ay), B)


def make_body(rng: np.random.Generator, width_px: float, view_height: int,
              cloth: tuple[np.ndarray, int] | None = None) -> Body:
    """A person seen from close by, front or back: head with hair, neck, torso, two arms in sleeves, hands.

    The outfit (fabric kind and colours, skin tone, hair colour) is `people.Outfit.sample`'s, so the bodies
    wear what the simulator's people wear; `cloth` (an sRGB texture and its side in view px) dresses the top in
    something else (`lookalike`: the picture itself).
    """
    from hvs_sim.scene.people import TOPS, Outfit, fabric_texture, hair_texture, skin_texture

    outfit = Outfit.sample(rng)
    B = float(width_px)
    pad = 4.0
    top = (HEAD_CENTRE + HEAD_AXES[1] + HAIR_RISE) * B + pad
    h = math.ceil(top + SPRITE_LENGTH * view_height)
    w = math.ceil(B * 1.06 + 2 * pad)
    ax, ay = (w - 1) / 2.0, top
    shape = (h, w)
    tile = max(16, round(TILE_OF_BODY * B))
    cloth = (_tile(cloth[0], cloth[1], shape) if cloth is not None else
             _tile(fabric_texture(outfit.top_fabric.kind, outfit.top_fabric.colours, outfit.top_fabric.seed,
                                  FABRIC_DRAW), tile, shape))
    tex_seed = int(rng.integers(2 ** 31))
    skin = _tile(skin_texture(outfit.skin, tex_seed), tile, shape)
    hair = _tile(hair_texture(outfit.hair, tex_seed + 1), tile, shape)

    parts = []  # (coverage mask, linear colour, half width for shading), back to front
    neck = _poly_mask(shape, _rounded_rect(ax - NECK[0] * B, ay - NECK[1] * B, ax + NECK[0] * B, ay + 0.1 * B, 0.02 * B))
    parts.append((neck, skin * 0.8, NECK[0] * B))  # the neck is in the head's shadow
    head_c = (ax, ay - HEAD_CENTRE * B)
    parts.append((_ellipse_mask(shape, head_c, (HEAD_AXES[0] * B, HEAD_AXES[1] * B)), skin, HEAD_AXES[0] * B))
    hair_mask = _ellipse_mask(shape, (ax, head_c[1] - HAIR_RISE * B), ((HEAD_AXES[0] + 0.02) * B, (HEAD_AXES[1] + 0.01) * B))
    if rng.uniform() < FACE_SHOWN:  # the face, below a curved hairline; seen from behind, hair all over
        face = _ellipse_mask(shape, (ax, head_c[1] + _u(rng, HAIRLINE) * B), (FACE_AXES[0] * B, FACE_AXES[1] * B))
        hair_mask *= 1.0 - face
    parts.append((hair_mask, hair, (HEAD_AXES[0] + 0.02) * B))
    torso = _poly_mask(shape, _torso_outline(ax, ay, B, h + B))
    parts.append((torso, cloth, TORSO_HALF * B))
    short = TOPS[outfit.top][1] == "short"
    for side in (-1, 1):
        x = ax + side * (TORSO_HALF + ARM_HALF - 0.01) * B
        arm = _poly_mask(shape, _rounded_rect(x - ARM_HALF * B, ay + ARM_TOP * B, x + ARM_HALF * B, ay + ARM_LENGTH * B,
                                              ARM_HALF * B))
        sleeve_end = ay + (SHORT_SLEEVE if short else ARM_LENGTH - 0.1) * B
        sleeve = arm.copy()
        sleeve[int(sleeve_end):] = 0.0
        forearm = arm - sleeve
        parts.append((forearm, skin, ARM_HALF * B * 0.8))
        parts.append((sleeve, cloth, ARM_HALF * B))
        hand = _ellipse_mask(shape, (x, ay + (ARM_LENGTH + 0.05) * B), (HAND_AXES[0] * B, HAND_AXES[1] * B))
        parts.append((hand, skin, HAND_AXES[0] * B))

    light = np.float32(_u(rng, PERSON_LIGHT))
    colour = np.zeros((h, w, 3), np.float32)  # premultiplied by the drawn coverage
    cover = np.zeros((h, w), np.float32)
    for m, c, half in parts:
        shaded = c * (_round_shade(m, half) * light)[..., None]
        colour = colour * (1.0 - m[..., None]) + shaded * m[..., None]
        cover = cover * (1.0 - m) + m
    colour = colour / np.maximum(cover, 1e-3)[..., None]  # un-premultiply: no dark fringe at anti-aliased edges
    alpha = cv2.GaussianBlur(cover, (0, 0), FEATHER_PX)
    rgba = np.dstack([colour * alpha[..., None], alpha]).astype(np.float32)
    return Body(rgba, (ax, ay), B)


# ---------------------------------------------------------------------------------------------------------------------
# Where the person is: (x, y, lean) of the shoulder-line centre in frame-0 image coordinates (the room)
# ---------------------------------------------------------------------------------------------------------------------


def _smooth(u: float) -> float:
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


@dataclass(frozen=True)
class PersonPath:
    """A person's motion for one kind; `pose(t)` is None while the person is not there."""

    kind: str
    params: dict

    def pose(self, t: float) -> tuple[float, float, float] | None:
        p = self.params
        if self.kind == "walk_by":
            x = p["x_mid"] + p["dir"] * p["speed"] * (t - p["t_mid"])
            y = p["y"] + p["bob"] * math.sin(2 * math.pi * p["step_hz"] * t + p["ph"])
            return x, y, p["lean"] * math.sin(math.pi * p["step_hz"] * t + p["ph"])
        t_in, t_stay, t_leave, t_out = p["t_in"], p["t_stay"], p["t_leave"], p["t_out"]
        if t < t_in or t > t_out:
            return None
        sway = p["sway"] * math.sin(2 * math.pi * p["sway_hz"] * t + p["ph"])
        x_here = p["x_stay"](t) + sway
        if t < t_stay:
            x = p["x_from"] + (x_here - p["x_from"]) * _smooth((t - t_in) / (t_stay - t_in))
        elif t > t_leave:
            x = x_here + (p["x_to"] - x_here) * _smooth((t - t_leave) / (t_out - t_leave))
        else:
            x = x_here
        return x, p["y"], p["lean"] * math.sin(2 * math.pi * p["sway_hz"] * t + 1.3 * p["ph"])


def _off_view(side: int, width_px: float, view_w: int) -> float:
    """x of a body's centre just out of view on the left (side −1) or the right (+1)."""
    return -width_px / 2 - OFF_MARGIN_PX if side < 0 else view_w + width_px / 2 + OFF_MARGIN_PX


def _person(kind: str, rng: np.random.Generator, roi, view: tuple[int, int], duration: float) -> tuple[PersonPath, float]:
    """The person's path and body width for a kind, placed against the ROI of frame 0."""
    x, y, rw, rh = roi
    gx, gy = x + (rw - 1) / 2.0, y + (rh - 1) / 2.0
    vw = view[0]
    r = min(1.0, duration / T_REF_S)  # short sequences: a compressed schedule
    side = 1 if rng.uniform() < 0.5 else -1
    if kind == "walk_by":
        full = _u(rng, WALK_FULL_FRAMES)
        cross = _u(rng, WALK_CROSS_S)
        k = full / (cross * FPS)
        B = float(np.clip((rw + k * vw) / (1.0 - k), *WALK_WIDTH_PX))  # covers the target `full` frames
        speed = (vw + B) / cross
        lead = (gx + B / 2 + OFF_MARGIN_PX) / speed if side > 0 else (vw - gx + B / 2 + OFF_MARGIN_PX) / speed
        # the body starts out of view when the sequence is long enough (short test sequences: as late as can be)
        t_mid = max(_u(rng, (0.35, 0.65)) * duration, min(lead, 0.65 * duration))
        params = {"x_mid": gx, "dir": side, "speed": speed, "t_mid": t_mid, "step_hz": _u(rng, STEP_HZ),
                  "bob": BOB * B, "lean": math.radians(LEAN_DEG), "ph": _u(rng, (0, 2 * np.pi))}
    elif kind in ("pause", "lookalike", "long", "hand"):
        B = (_u(rng, LONG_WIDTH_PX) if kind == "long" else rw * _u(rng, HAND_WIDTH_OF_ROI) if kind == "hand" else
             _u(rng, PAUSE_WIDTH_PX))
        stay = {"long": LONG_STAY_S, "hand": HAND_STAY_S}.get(kind, PAUSE_STAY_S)
        t_in = _u(rng, PAUSE_START) * duration
        t_stay = t_in + _u(rng, PAUSE_MOVE_S) * r
        t_leave = t_stay + _u(rng, stay) * r
        t_out = t_leave + _u(rng, PAUSE_MOVE_S) * r
        stop = gx + rng.uniform(-PAUSE_OFFSET, PAUSE_OFFSET) * (B - rw) / 2
        params = {"t_in": t_in, "t_stay": t_stay, "t_leave": t_leave, "t_out": t_out, "x_stay": lambda t, s=stop: s,
                  "x_from": _off_view(-side, B, vw), "x_to": _off_view(side if rng.uniform() < 0.5 else -side, B, vw),
                  "sway": _u(rng, SWAY_PX), "sway_hz": _u(rng, SWAY_HZ), "lean": math.radians(_u(rng, SWAY_DEG))}
    elif kind == "partial":
        B = _u(rng, PARTIAL_WIDTH_PX)
        lo, hi = PARTIAL_COVER
        mid = _u(rng, (lo + 0.1, hi - 0.1))
        amp = min(mid - lo, hi - mid)
        hz, ph = _u(rng, PARTIAL_HZ), _u(rng, (0, 2 * np.pi))

        def x_stay(t, side=side, mid=mid, amp=amp, hz=hz, ph=ph, B=B):
            cover = mid + amp * math.sin(2 * math.pi * hz * t + ph)
            edge = gx + side * (rw / 2 - cover * rw)  # the body's inner edge, the covered share from its side
            return edge + side * B / 2

        t_in = _u(rng, PARTIAL_START) * duration
        t_leave = _u(rng, PARTIAL_END) * duration
        params = {"t_in": t_in, "t_stay": t_in + _u(rng, PARTIAL_MOVE_S) * r, "t_leave": t_leave,
                  "t_out": t_leave + _u(rng, PARTIAL_MOVE_S) * r, "x_stay": x_stay, "x_from": _off_view(side, B, vw),
                  "x_to": _off_view(side, B, vw), "sway": 0.0, "sway_hz": _u(rng, SWAY_HZ),
                  "lean": math.radians(_u(rng, SWAY_DEG))}
    else:  # pragma: no cover - kinds are checked by the caller
        raise choice_error("kind", kind, ALL_KINDS)
    params["y"] = gy if kind == "hand" else gy - rh / 2 - _u(rng, SHOULDER_ABOVE_ROI) * B  # a hand: its centre
    params.setdefault("ph", _u(rng, (0, 2 * np.pi)))
    return PersonPath(kind, params), B


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

    source: one of NATURAL_SOURCES; kind: one of ALL_KINDS; camera: a `camera_model` preset (`ideal`
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


# ---------------------------------------------------------------------------------------------------------------------
# The benchmark
# ---------------------------------------------------------------------------------------------------------------------

VISIBLE_BELOW = 0.4  # the visible_lt_40 split: frames with true occlusion < 40 %
PREVIEW_SCALE = 0.5  # contact-sheet thumbnails
SHEET_SEQUENCES = 6
TIMING_REFERENCE = "ecc"


@dataclass(frozen=True)
class NaturalBenchConfig:
    methods: tuple[str, ...] = ("ecc", "deep_lk", "hybrid")
    sources: tuple[str, ...] = NATURAL_SOURCES
    kinds: tuple[str, ...] = NATURAL_KINDS
    seeds: tuple[int, ...] = DEFAULT_SEEDS
    frames: int = 150
    camera: str = REALISTIC_PRESET
    workers: int = 1
    threads: int = 1  # torch threads per process: timings on a shared machine stay comparable
    motion: str = "hand"  # MOTIONS

    def __post_init__(self):
        if self.motion not in MOTIONS:
            raise choice_error("natural motion", self.motion, tuple(MOTIONS))
        for s in self.sources:
            if s not in NATURAL_SOURCES:
                raise choice_error("natural source", s, NATURAL_SOURCES)
        for k in self.kinds:
            if k not in ALL_KINDS:
                raise choice_error("natural kind", k, ALL_KINDS)
        from hvs_sim.tracking import TRACKER_NAMES

        for m in self.methods:
            if m not in TRACKER_NAMES:
                raise choice_error("tracker", m, TRACKER_NAMES)
        sensor_preset(self.camera)
        if not self.methods or not self.sources or not self.kinds or not self.seeds:
            raise ConfigError("natural benchmark needs at least one method, source, kind and seed")


def _previews(seq: NaturalSequence) -> tuple[np.ndarray, np.ndarray, int]:
    """Frame 0 with the ROI, and the frame of peak occlusion (the last frame if none) with the true target position,
    half size."""
    gt = seq.gt_track
    f0 = seq.frames[0].copy()
    x, y, w, h = seq.roi
    cv2.rectangle(f0, (x, y), (x + w - 1, y + h - 1), (0, 255, 0), 2)
    k = int(np.argmax(seq.occlusion)) if seq.occlusion.max() > 0 else len(seq.frames) - 1
    fk = seq.frames[k].copy()
    cv2.drawMarker(fk, tuple(round(v) for v in gt[k]), (0, 255, 0), cv2.MARKER_CROSS, 24, 2)
    small = [cv2.resize(f, None, fx=PREVIEW_SCALE, fy=PREVIEW_SCALE, interpolation=cv2.INTER_AREA) for f in (f0, fk)]
    return small[0], small[1], k


def _natural_job(args):
    import torch

    from hvs_sim.bench.track import run_tracker

    source, kind, seed, frames, methods, camera, threads, motion = args
    torch.set_num_threads(threads)
    seq = make_natural_sequence(source, kind, seed, n_frames=frames, camera=camera, motion=motion)
    res = {m: run_tracker(m, seq) for m in methods}
    f0, fk, k = _previews(seq)
    meta = {"roi": list(seq.roi), "generate_s": seq.seconds, "peak_occlusion": float(seq.occlusion.max()),
            "frames_occluded_ge_90": int(np.sum(seq.occlusion >= 0.9)), "peak_frame": k,
            "max_gt_step_px": float(np.linalg.norm(np.diff(seq.gt_track, axis=0), axis=1).max()),
            "blur_samples_mean": float(seq.blur_samples.mean()), "preview": (f0, fk)}
    return (source, kind, seed), res, meta


def run_natural_bench(config: NaturalBenchConfig, out: Path, progress: bool = True) -> dict:
    """Every method on every (source, kind, seed) sequence; writes summary.json, frames.csv, table.md and figures."""

    from hvs_sim.bench.track import summarize

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(s, k, seed, config.frames, config.methods, config.camera, config.threads, config.motion)
            for s in config.sources for k in config.kinds for seed in config.seeds]
    results, metas = {}, {}
    for key, res, meta in collect_jobs(_natural_job, jobs, config, out, "bench natural", "seq", progress):
        results[key], metas[key] = res, meta

    def label(key) -> str:
        return f"{key[0]}/{key[1]}/s{key[2]}"

    def visible(r):
        return r["occlusion"] < VISIBLE_BELOW

    summary = {"config": config_json(config),
               "per_sequence": {}, "per_kind": {}, "overall": {}, "visible_lt_40": {}, "unoccluded_sequences": {},
               "timing": {}, "generation": {}}
    for key in results:
        meta = {k: v for k, v in metas[key].items() if k != "preview"}
        summary["per_sequence"][label(key)] = {**meta, "methods": {m: summarize([results[key][m]]) for m in config.methods}}
    for m in config.methods:
        rs = [results[k][m] for k in results]
        summary["overall"][m] = summarize(rs)
        summary["visible_lt_40"][m] = summarize(rs, visible)
        for kind in config.kinds:
            summary["per_kind"].setdefault(kind, {})[m] = summarize([results[k][m] for k in results if k[1] == kind])
        clear = [results[k][m] for k in results if k[1] == "clear"]
        if clear:
            err = np.concatenate([r["error"][1:] for r in clear])
            summary["unoccluded_sequences"][m] = {"sequences": len(clear), "frames": int(err.size),
                                                  "max_px": float(err.max()), "frames_gt_2px": int(np.sum(err > 2.0))}
    ref = summary["overall"].get(TIMING_REFERENCE, {}).get("median_ms")
    for m in config.methods:
        med = summary["overall"][m]["median_ms"]
        summary["timing"][m] = {"median_ms": med, f"ratio_to_{TIMING_REFERENCE}": (med / ref) if ref else None}
    gen = np.array([metas[k]["generate_s"] for k in metas])
    summary["generation"] = {"sequences": int(gen.size), "median_s": float(np.median(gen)), "max_s": float(gen.max()),
                             "frames_per_sequence": config.frames}
    write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    write_frames_csv(results, out / "frames.csv", ("source", "kind", "seed"))
    (out / "table.md").write_text(natural_table(summary))
    natural_figures(results, metas, config, out)
    return summary


def natural_table(summary: dict) -> str:
    """table.md: overall, visible frames, per kind, per sequence (≤2 px %), timing against ECC."""
    head = ["| method | frames | ≤1 px | ≤2 px | median px | p95 px | max px | median ms | lost | predict |",
            "|---|---|---|---|---|---|---|---|---|---|"]

    def row(name, s):
        if not s.get("frames"):
            return f"| {name} | 0 | | | | | | | | |"
        return (f"| {name} | {s['frames']} | {s['pct_le_1px']:.1f} % | {s['pct_le_2px']:.1f} % | {s['median_px']:.2f} | "
                f"{s['p95_px']:.2f} | {s['max_px']:.1f} | {s['median_ms']:.1f} | {s['pct_lost']:.1f} % | "
                f"{s['pct_predict']:.1f} % |")

    cfg = summary["config"]
    intro = (f"Natural imagery: {len(cfg['sources'])} sources × kinds {', '.join(cfg['kinds'])} × seeds "
             f"{', '.join(map(str, cfg['seeds']))}, {cfg['frames']} frames, camera {cfg['camera']}.")
    text = [intro, "",
            "## All sequences, all frames", "", *head, *[row(m, v) for m, v in summary["overall"].items()],
            "", "## Frames with true occlusion < 40 %", "", *head,
            *[row(m, v) for m, v in summary["visible_lt_40"].items()]]
    for kind, per in summary["per_kind"].items():
        text += ["", f"## {kind}", "", *head, *[row(m, v) for m, v in per.items()]]
    if summary["unoccluded_sequences"]:
        text += ["", "## Unoccluded sequences (clear): worst error", "", "| method | sequences | frames | max px | frames > 2 px |",
                 "|---|---|---|---|---|"]
        text += [f"| {m} | {v['sequences']} | {v['frames']} | {v['max_px']:.2f} | {v['frames_gt_2px']} |"
                 for m, v in summary["unoccluded_sequences"].items()]
    methods = list(summary["overall"])
    text += ["", "## Per sequence: ≤2 px % (peak true occlusion)", "",
             "| sequence | peak occ. | " + " | ".join(methods) + " |", "|---|---|" + "---|" * len(methods)]
    for name, s in summary["per_sequence"].items():
        cells = [f"{s['methods'][m]['pct_le_2px']:.0f}" for m in methods]
        if "hybrid" in methods:  # bold where the hybrid is behind another method
            best = max(s["methods"][m]["pct_le_2px"] for m in methods)
            i = methods.index("hybrid")
            if s["methods"]["hybrid"]["pct_le_2px"] < best:
                cells[i] = f"**{cells[i]}**"
        text.append(f"| {name} | {100 * s['peak_occlusion']:.0f} % | " + " | ".join(cells) + " |")
    text += ["", f"## Timing (median ms per frame; ratio to {TIMING_REFERENCE} in the same run)", "",
             f"| method | median ms | × {TIMING_REFERENCE} |", "|---|---|---|"]
    for m, v in summary["timing"].items():
        ratio = v[f"ratio_to_{TIMING_REFERENCE}"]
        text.append(f"| {m} | {v['median_ms']:.1f} | {'' if ratio is None else f'{ratio:.2f}'} |")
    g = summary["generation"]
    gen = (f"Generation: median {g['median_s']:.1f} s (max {g['max_s']:.1f} s) per sequence of "
           f"{g['frames_per_sequence']} frames.")
    text += ["", gen]
    return "\n".join(text) + "\n"


def _sheet_keys(keys: list, n: int) -> list:
    """Sequences for the contact sheet: one per kind, then more occluded ones; each from a new source while any is left."""
    chosen, sources = [], set()
    all_sources = {q[0] for q in keys}

    def take(k) -> None:
        chosen.append(k)
        sources.add(k[0])

    for kind in (*OCCLUDED_KINDS, "clear"):
        for k in keys:
            if k[1] == kind and (k[0] not in sources or sources == all_sources):
                take(k)
                break
    for occluded in (True, False):
        for k in keys:
            if len(chosen) < n and k not in chosen and (k[1] != "clear") == occluded \
                    and (k[0] not in sources or sources == all_sources):
                take(k)
    return chosen[:n]


def natural_figures(results: dict, metas: dict, config: NaturalBenchConfig, out: Path) -> list[Path]:
    """fig_natural.png (CDF of the error per method: all, per kind, visible frames) and sequences.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hvs_sim.viz.figures import method_colour

    panels = [("all frames", list(results), None)] + [(k, [q for q in results if q[1] == k], None) for k in config.kinds]
    panels.append((f"occlusion < {VISIBLE_BELOW:.0%}", list(results), VISIBLE_BELOW))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.0), squeeze=False)
    for ax, (title, keys, below) in zip(axes[0], panels):
        for m in config.methods:
            errs = [results[k][m]["error"][1:] if below is None else
                    results[k][m]["error"][1:][results[k][m]["occlusion"][1:] < below] for k in keys]
            err = np.concatenate(errs) if errs else np.array([])
            if err.size:
                xs = np.sort(err)
                ax.plot(np.maximum(xs, 1e-3), np.arange(1, xs.size + 1) / xs.size, label=m, color=method_colour(m))
        ax.axvline(2.0, ls="--", color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlim(1e-2, 1e3)
        ax.set_ylim(0, 1)
        ax.set_xlabel("error (px)")
        ax.set_title(title)
    axes[0][0].set_ylabel("fraction of frames ≤ error")
    axes[0][0].legend(fontsize=8, loc="upper left")
    fig.suptitle(f"Natural imagery ({config.camera}): CDF of the tracking error")
    fig.tight_layout()
    p1 = Path(out) / "fig_natural.png"
    fig.savefig(p1, dpi=90)
    plt.close(fig)

    keys = _sheet_keys(list(results), SHEET_SEQUENCES)
    fig, axes = plt.subplots(len(keys), 2, figsize=(8, 3.1 * len(keys)), squeeze=False)
    for row, k in zip(axes, keys):
        f0, fk = metas[k]["preview"]
        row[0].imshow(f0)
        row[0].set_title(f"{k[0]} {k[1]} s{k[2]}: frame 0, ROI", fontsize=9)
        row[1].imshow(fk)
        what = (f"peak occlusion {100 * metas[k]['peak_occlusion']:.0f} %" if metas[k]["peak_occlusion"] > 0
                else "last frame")
        row[1].set_title(f"frame {metas[k]['peak_frame']}: {what}, true centre", fontsize=9)
        for a in row:
            a.axis("off")
    fig.tight_layout()
    p2 = Path(out) / "sequences.png"
    fig.savefig(p2, dpi=80)
    plt.close(fig)
    return [p1, p2]


def smoke_config(methods: tuple[str, ...], camera: str = REALISTIC_PRESET, workers: int = 1) -> NaturalBenchConfig:
    """A tiny run that checks the pipeline end to end: one source, walk_by, 40 frames. Not a result."""
    return NaturalBenchConfig(methods=methods, sources=NATURAL_SOURCES[:1], kinds=("walk_by",), seeds=DEFAULT_SEEDS[:1],
                              frames=40, camera=camera, workers=workers)

