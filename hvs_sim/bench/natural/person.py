"""The person close to the lens: the drawn body (or hand) as a premultiplied sprite, and where it is over time for
each occluder kind (crossing, pausing, standing beside, a hand held over the target)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.bench.natural.sources import ALL_KINDS, FPS, T_REF_S, _u
from hvs_sim.errors import choice_error
from hvs_sim.sensor import decode, encode

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
