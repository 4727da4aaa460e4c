"""What a real camera does to the light: exposure, auto-exposure, sensor noise, compression, lens distortion.

`SensorModel` is a frozen, seeded description of a camera; `SENSOR_PRESETS` is the one registry of
named presets (`ideal`, `webcam`, `phone_handheld`, `low_light`) that the scene config, the CLI and
the benchmarks read. The frame pipeline (applied by `hvs_sim.render.Renderer` to every RGB frame):

    render(s) at sub-frame instants of the exposure, in linear light (sRGB decoded), averaged (motion blur)
    → lens distortion (optional; ground truth goes through the same model)
    → electrons = radiance × white_e;  + shot noise (Poisson ≈ Gaussian, var = electrons) + read noise
    → × auto-exposure gain → clip (saturation) → sRGB encode → 8 bit → JPEG at the preset's quality

Units: exposure in ms, noise in electrons (e⁻), light and gain changes as fractions. `white_e` is
the charge a white surface (linear radiance 1) leaves in a pixel over one exposure at the modelled
light level: indoors that is a small part of the full well, so shot noise is large. Auto-exposure
here changes the gain only, never the exposure time (which fixes the motion blur).

Not modelled (say so before trusting a result that depends on them): rolling shutter, the ISP's
denoising and sharpening (a phone's video is cleaner than `phone_handheld`'s raw noise), demosaicing
(noise here is independent per channel), vignetting, and the frame-to-frame prediction of a video
codec (per-frame JPEG stands in for its artefacts). `ideal` has every effect off and leaves the
render untouched (bit for bit). This module is numpy and OpenCV (single-threaded SIMD arithmetic for the per-pixel
work: no thread pool to oversubscribe on a busy 2-core machine) and knows nothing of MuJoCo, so the scene config can
hold a `SensorModel` and the renderer can apply it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from types import MappingProxyType

import cv2
import numpy as np

from hvs_sim.errors import ConfigError, choice_error

NOISE_STREAM = 23  # seed stream of the sensor noise (rng = default_rng([seed, NOISE_STREAM, frame]))
DRIFT_STREAM = 29  # seed stream of the phases of auto-exposure drift and light changes
STILL_STREAM = 31  # seed stream of the noise of still captures (Renderer.still_average), apart from the episode's
NOISE_BANK_FRAMES = 3  # normals drawn once per episode, read at two random offsets per frame: 2 ms instead of 10 ms
SQRT_HALF = math.sqrt(0.5)  # the bank is stored × this, so the sum of its two windows is N(0, 1) with no third pass
AE_METER_SIZE = (80, 60)  # auto-exposure meters a thumbnail of the frame
AE_METER_SIGMA = 0.35  # centre weighting of the meter, as a fraction of the image diagonal
LINEAR_LEVELS = 4096  # 12-bit linear quantisation before the sRGB curve (a real ADC's depth)
BLUR_STEP_PX = 1.5  # at most this much image motion between two sub-frame renders (or field taps) of one exposure
BLUR_MODES = ("subframes", "field")  # SensorModel.blur, the default first
SUBFRAME_SCALE_MAX = 4  # SensorModel.blur_subframe_scale: smaller renders than 1/4 the size keep too little of the light
SUBFRAME_SMALL_MIN = 3  # ... and only from this many sub-frames: the small path renders the middle one twice (full and
# small), and at 2 sub-frames that costs about what the 2 full-size renders do (a half-size render ≈ 0.4× a full one)
FIELD_MAX_TAPS = 32  # field blur: most taps along a pixel's motion (48 px of motion at BLUR_STEP_PX)
MAX_EXPOSURE_MS = 200.0  # a scenario also caps it at one frame interval (1000 / fps)
MAX_LENS_RADIUS = 1.0  # distortion must not fold over out to this normalised radius (a 90° diagonal field of view)
LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)  # Rec. 709 luminance weights of linear RGB
MIN_METERED = 1e-4  # a black frame still gives a finite auto-exposure gain (then clipped to the range)


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 decoding, v in [0, 1]."""
    v = np.asarray(v, np.float32)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 encoding, v in [0, 1]."""
    v = np.asarray(v, np.float32)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(np.maximum(v, 0), 1 / 2.4) - 0.055).astype(np.float32)


_DECODE_LUT = srgb_to_linear(np.arange(256) / 255.0)
_ENCODE_LUT = np.clip(np.round(255 * linear_to_srgb(np.arange(LINEAR_LEVELS) / (LINEAR_LEVELS - 1))), 0, 255).astype(np.uint8)
# The ADC's code (uint16, saturated by OpenCV's conversion: below 0 reads 0) → the 8-bit sRGB output, one gather: codes
# above the ADC's full scale read its top entry, so the table is the clip at saturation too.
_ENCODE_LUT16 = np.concatenate([_ENCODE_LUT, np.full(65536 - LINEAR_LEVELS, _ENCODE_LUT[-1], np.uint8)])
LUT_MAX_CHANNELS = 4  # cv2.LUT takes images of up to this many channels (one channel comes back without its axis)


def decode(frame: np.ndarray) -> np.ndarray:
    """uint8 sRGB → float32 linear radiance in [0, 1] (a table lookup: OpenCV's for images, 14× numpy's gather)."""
    frame = np.asarray(frame)
    if frame.dtype == np.uint8 and (frame.ndim == 2 or (frame.ndim == 3 and 2 <= frame.shape[2] <= LUT_MAX_CHANNELS)):
        return cv2.LUT(np.ascontiguousarray(frame), _DECODE_LUT)
    return _DECODE_LUT[frame]


def encode(linear: np.ndarray, gain: float = 1.0) -> np.ndarray:
    """float32 linear in [0, 1] (× gain, then clipped: saturation) → uint8 sRGB through a 12-bit ADC."""
    linear = np.ascontiguousarray(linear, np.float32)
    flat = linear.reshape(linear.shape[0], -1)
    return _adc_to_srgb(cv2.addWeighted(flat, float(gain) * (LINEAR_LEVELS - 1), flat, 0.0, 0.0, dtype=cv2.CV_16U),
                        linear.shape)


def _adc_to_srgb(codes: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """ADC codes (uint16, rounded to nearest, saturated; the gain already in their scale) → uint8 sRGB of `shape`: the
    ADC's clip at full scale and the sRGB curve are the one table `_ENCODE_LUT16` (numpy's gather on a uint16 index:
    half the time of an int32 one, 64 KiB in cache)."""
    return np.take(_ENCODE_LUT16, codes).reshape(shape)


@dataclass(frozen=True)
class SensorModel:
    """A camera's capture model. Defaults are `ideal`: every effect off.

    exposure_ms: shutter time; the exposure ends at the frame time (ground truth time), so the image
        lags the geometry by exposure/2 on average. 0 = instantaneous (no motion blur).
    blur_max_samples: most sub-frame renders averaged over the exposure; as many are used as keep
        the image motion between two of them ≤ BLUR_STEP_PX (1 when nothing moves fast).
    blur: how motion blur is made. "subframes" (default): sub-frame renders averaged, one render each;
        "field": one render at mid-exposure, blurred along every pixel's image motion over the exposure
        (from its depth, the camera's and the moving bodies' motion, `hvs_sim.render.blur`), taps
        BLUR_STEP_PX apart, at most blur_max_samples. docs/results.md
        ("Motion blur from the motion field") has its error against the reference and its cost.
    blur_subframe_scale: with "subframes" and at least SUBFRAME_SMALL_MIN sub-frames, every sub-frame is
        rendered at 1/scale the width and height and the middle one at full size too; the small ones' mean,
        enlarged, is the exposure's light, plus the middle one's fine detail (full minus its small render)
        where the sub-frames agree and 1/n of it where the image moves (`hvs_sim.render.blur.combine_subframes`).
        1 (the default, every preset): every sub-frame a full-size render (the reference). 2 renders a
        4-sub-frame exposure ~1.3× faster but lengthens the blur (a 7.4 px blur fits an 8.9 px box:
        docs/results.md, "Small sub-frames"), so it stays opt-in.
    white_e: electrons from a white surface over the exposure (light × exposure × pixel area × QE);
        shot noise has variance = electrons, so fewer electrons mean more noise. inf = no shot noise.
    read_noise_e: read noise, electrons RMS.
    ae_target: auto-exposure target, the metered (centre-weighted) mean linear luminance; 0 = off
        (gain fixed at 1).
    ae_time_s: auto-exposure time constant (first-order lag in log gain, one frame of delay).
    ae_gain_range: (min, max) gain the auto-exposure may use.
    ae_drift: relative amplitude of slow drift of the auto-exposure target, at ae_drift_hz.
    light_flicker / light_flicker_hz: relative amplitude and frequency of a flickering light (a
        failing fluorescent tube, a lamp on a dimmer); sampled at each sub-frame render.
    light_dim / light_dim_period_s: the scene's lights dim by up to this fraction and back, over
        this period (a cloud passing a window, a dimmer).
    jpeg_quality: 1..100 per-frame JPEG (the artefacts of an intra-coded video stream); 0 = off.
    distortion: OpenCV (k1, k2, p1, p2, k3) radial/tangential lens distortion; () = none.
    """

    name: str = "ideal"
    exposure_ms: float = 0.0
    blur_max_samples: int = 1
    blur: str = "subframes"
    blur_subframe_scale: int = 1
    white_e: float = math.inf
    read_noise_e: float = 0.0
    ae_target: float = 0.0
    ae_time_s: float = 0.3
    ae_gain_range: tuple[float, float] = (0.25, 8.0)
    ae_drift: float = 0.0
    ae_drift_hz: float = 0.1
    light_flicker: float = 0.0
    light_flicker_hz: float = 2.0
    light_dim: float = 0.0
    light_dim_period_s: float = 6.0
    jpeg_quality: int = 0
    distortion: tuple[float, ...] = ()

    def __post_init__(self):
        for name in ("ae_gain_range", "distortion"):  # tuples of floats, so the model stays hashable and comparable
            v = getattr(self, name)
            try:
                object.__setattr__(self, name, tuple(float(x) for x in v))
            except (TypeError, ValueError):
                raise ConfigError(f"sensor {name} must be a tuple of numbers, got {v!r}") from None
        _check_range("exposure_ms", self.exposure_ms, 0.0, MAX_EXPOSURE_MS)
        if isinstance(self.blur_max_samples, bool) or not isinstance(self.blur_max_samples, (int, np.integer)) \
                or not 1 <= self.blur_max_samples <= 32:
            raise ConfigError(f"sensor blur_max_samples must be an int in [1, 32], got {self.blur_max_samples!r}")
        if isinstance(self.blur_subframe_scale, bool) or not isinstance(self.blur_subframe_scale, (int, np.integer)) \
                or not 1 <= self.blur_subframe_scale <= SUBFRAME_SCALE_MAX:
            raise ConfigError(f"sensor blur_subframe_scale must be an int in [1, {SUBFRAME_SCALE_MAX}], got "
                              f"{self.blur_subframe_scale!r}")
        if self.blur not in BLUR_MODES:
            raise choice_error("sensor blur", self.blur, BLUR_MODES)
        if self.blur != BLUR_MODES[0] and self.exposure_ms <= 0:
            raise ConfigError(f"sensor blur={self.blur!r} makes motion blur over the exposure: it needs exposure_ms > 0 "
                              f"(got {self.exposure_ms})")
        if not (isinstance(self.white_e, (int, float)) and (self.white_e == math.inf or 10 <= self.white_e <= 1e6)):
            raise ConfigError(f"sensor white_e must be in [10, 1e6] electrons or inf (no shot noise), got {self.white_e!r}")
        _check_range("read_noise_e", self.read_noise_e, 0.0, 100.0)
        if self.read_noise_e > 0 and self.white_e == math.inf:
            raise ConfigError("sensor read_noise_e needs a finite white_e (electrons from white) to be measured against")
        _check_range("ae_target", self.ae_target, 0.0, 0.9)
        _check_range("ae_time_s", self.ae_time_s, 0.01, 10.0)
        lo, hi = self.ae_gain_range if len(self.ae_gain_range) == 2 else (math.nan, math.nan)
        if not (0.01 <= lo <= 1.0 <= hi <= 64.0):
            raise ConfigError(f"sensor ae_gain_range must be (min, max) with 0.01 <= min <= 1 <= max <= 64, got {self.ae_gain_range!r}")
        _check_range("ae_drift", self.ae_drift, 0.0, 0.5)
        _check_range("ae_drift_hz", self.ae_drift_hz, 0.0, 5.0)
        _check_range("light_flicker", self.light_flicker, 0.0, 0.5)
        _check_range("light_flicker_hz", self.light_flicker_hz, 0.0, 15.0)
        _check_range("light_dim", self.light_dim, 0.0, 0.9)
        _check_range("light_dim_period_s", self.light_dim_period_s, 0.5, 600.0)
        if isinstance(self.jpeg_quality, bool) or not isinstance(self.jpeg_quality, (int, np.integer)) \
                or not 0 <= self.jpeg_quality <= 100:
            raise ConfigError(f"sensor jpeg_quality must be an int in [1, 100], or 0 for no compression, got {self.jpeg_quality!r}")
        if len(self.distortion) not in (0, 4, 5) or not all(math.isfinite(v) and abs(v) < 2 for v in self.distortion):
            raise ConfigError(f"sensor distortion must be () or OpenCV (k1, k2, p1, p2[, k3]) with |k| < 2, got {self.distortion!r}")
        if self.distortion and not _monotonic(self.distortion):
            raise ConfigError(f"sensor distortion {self.distortion} folds the image over itself within "
                              f"{MAX_LENS_RADIUS} focal lengths of the centre (the radius must grow with the angle)")

    @property
    def is_ideal(self) -> bool:
        """True when every effect is off: the renderer then returns its render untouched."""
        return all(getattr(self, f.name) == f.default for f in fields(self) if f.name != "name")

    @property
    def lights_change(self) -> bool:
        return self.light_flicker > 0 or self.light_dim > 0

    def exposure_offsets(self, n: int) -> np.ndarray:
        """Seconds before the frame time of n sub-frame instants: midpoints of n equal parts of the exposure."""
        return self.exposure_ms * 1e-3 * (1.0 - (np.arange(n) + 0.5) / n)

    def samples_for_motion(self, motion_px: float) -> int:
        """Sub-frame renders needed so that consecutive ones are ≤ BLUR_STEP_PX apart in the image."""
        if self.exposure_ms <= 0:
            return 1
        return int(np.clip(math.ceil(motion_px / BLUR_STEP_PX), 1, self.blur_max_samples))


def _monotonic(distortion: tuple[float, ...]) -> bool:
    """Radial part r(1 + k1 r² + k2 r⁴ + k3 r⁶) increasing out to MAX_LENS_RADIUS (no fold-over)."""
    k1, k2 = distortion[0], distortion[1]
    k3 = distortion[4] if len(distortion) == 5 else 0.0
    r = np.linspace(0.0, MAX_LENS_RADIUS, 400)
    return bool(np.all(np.diff(r * (1 + k1 * r**2 + k2 * r**4 + k3 * r**6)) > 0))


def _check_range(name: str, v, lo: float, hi: float) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not lo <= float(v) <= hi:
        raise ConfigError(f"sensor {name} must be a number in [{lo}, {hi}], got {v!r}")


# One registry of presets. Figures are typical of the class of camera, not of one product.
SENSOR_PRESETS: Mapping[str, SensorModel] = MappingProxyType({
    "ideal": SensorModel(),
    # indoor USB webcam: long exposure, MJPEG, mild barrel distortion, an unsteady lamp
    "webcam": SensorModel(
        name="webcam", exposure_ms=20.0, blur_max_samples=6, white_e=1500.0, read_noise_e=6.0,
        ae_target=0.18, ae_time_s=0.5, ae_drift=0.05, ae_drift_hz=0.08, light_flicker=0.03, light_flicker_hz=1.3,
        jpeg_quality=75, distortion=(-0.08, 0.03, 0.0, 0.0, 0.0)),
    # phone video held in the hand: short exposure, small pixels, fast AE, compression (per-frame JPEG
    # for the video codec), daylight through a window dimming and back; the phone's ISP undistorts
    "phone_handheld": SensorModel(
        name="phone_handheld", exposure_ms=8.0, blur_max_samples=6, white_e=800.0, read_noise_e=3.0,
        ae_target=0.18, ae_time_s=0.25, ae_drift=0.08, ae_drift_hz=0.12, light_dim=0.25, light_dim_period_s=5.0,
        jpeg_quality=60),
    # a machine-vision camera on a robot's wrist in a lit cell: exposure and gain fixed when the goal is taught (no
    # auto-exposure), a short global-shutter exposure, large pixels (many electrons), lossless transfer, steady
    # lights, a calibrated (undistorted) lens
    "robot_cell": SensorModel(
        name="robot_cell", exposure_ms=2.0, blur_max_samples=3, white_e=12000.0, read_noise_e=5.0, jpeg_quality=0),
    # dim room: few electrons, long exposure, high gain, a flickering tube: blur and noise dominate
    "low_light": SensorModel(
        name="low_light", exposure_ms=33.0, blur_max_samples=8, white_e=150.0, read_noise_e=4.0,
        ae_target=0.18, ae_time_s=0.4, ae_gain_range=(0.25, 16.0), ae_drift=0.05, light_flicker=0.05,
        light_flicker_hz=2.0, jpeg_quality=70),
})
SENSOR_NAMES: tuple[str, ...] = tuple(SENSOR_PRESETS)
REALISTIC_PRESET = "phone_handheld"  # what the benchmarks use by default


def sensor_preset(name: str | SensorModel, **overrides) -> SensorModel:
    """A named preset (or a model), with any field replaced."""
    if isinstance(name, SensorModel):
        base = name
    elif isinstance(name, str) and name in SENSOR_PRESETS:
        base = SENSOR_PRESETS[name]
    else:
        raise choice_error("camera preset", name, SENSOR_NAMES)
    unknown = set(overrides) - {f.name for f in fields(SensorModel)}
    if unknown:
        raise ConfigError(f"unknown sensor setting(s) {sorted(unknown)}; accepted: {[f.name for f in fields(SensorModel)]}")
    return replace(base, **overrides) if overrides else base


# ---------------------------------------------------------------- lights and exposure over time


@functools.lru_cache(maxsize=64)
def _phases(seed: int) -> np.ndarray:
    return np.random.default_rng([seed, DRIFT_STREAM]).uniform(0, 2 * np.pi, 3)


def light_scale(model: SensorModel, seed: int, t: float) -> float:
    """Factor on the scene's light intensities at time t (1 = as modelled)."""
    ph = _phases(seed)
    dim = model.light_dim * 0.5 * (1 - math.cos(2 * math.pi * t / model.light_dim_period_s + ph[0]))
    flick = model.light_flicker * math.sin(2 * math.pi * model.light_flicker_hz * t + ph[1])
    return max(0.0, (1.0 - dim) * (1.0 + flick))


def _meter(linear: np.ndarray) -> float:
    """Centre-weighted mean luminance of a linear frame, as an auto-exposure meters it."""
    thumb = cv2.resize(linear, AE_METER_SIZE, interpolation=cv2.INTER_AREA)
    return float(((thumb @ LUMA) * _METER_WEIGHTS).sum())


def _meter_weights() -> np.ndarray:
    w, h = AE_METER_SIZE
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (w * w + h * h)
    weight = np.exp(-r2 / (2 * AE_METER_SIGMA ** 2)).astype(np.float32)
    return weight / weight.sum()


_METER_WEIGHTS = _meter_weights()


class SensorState:
    """The stateful part of a camera: its auto-exposure gain, updated once per frame, and the noise bank."""

    def __init__(self, model: SensorModel, seed: int, shape: tuple[int, int]):
        self.model, self.seed = model, seed
        self.gain: float | None = None  # set from the first frame's meter reading (AE starts converged)
        n = int(np.prod(shape)) * 3
        bank_rng = np.random.default_rng([seed, NOISE_STREAM])
        self._bank = bank_rng.standard_normal(n * NOISE_BANK_FRAMES, dtype=np.float32)
        self._bank *= np.float32(SQRT_HALF)
        self._n = n
        self._drift_phase = _phases(seed)[2]

    def _ae_target(self, t: float) -> float:
        m = self.model
        return m.ae_target * (1 + m.ae_drift * math.sin(2 * math.pi * m.ae_drift_hz * t + self._drift_phase))

    def _update_gain(self, metered: float, t: float, dt: float) -> None:
        """First-order lag in log gain towards the gain that would meet the target."""
        m = self.model
        lo, hi = m.ae_gain_range
        want = float(np.clip(self._ae_target(t) / max(metered, MIN_METERED), lo, hi))
        if self.gain is None:
            self.gain = want
        else:
            a = 1.0 - math.exp(-dt / m.ae_time_s)
            self.gain = float(np.clip(math.exp((1 - a) * math.log(self.gain) + a * math.log(want)), lo, hi))

    def capture(self, linear: np.ndarray, frame: int, t: float, dt: float, stream: int = NOISE_STREAM) -> np.ndarray:
        """Linear radiance (H×W×3 float32, [0, 1]) → the uint8 RGB frame the camera delivers. `stream` keys the
        noise with `frame` (STILL_STREAM: frames that must not share noise with the episode's)."""
        m = self.model
        if m.ae_target > 0:
            metered = _meter(linear)
            if self.gain is None:
                self._update_gain(metered, t, dt)
            gain: float = self.gain  # type: ignore[assignment]  # set by _update_gain on the first frame
            self._update_gain(metered, t, dt)  # this frame's reading sets the next frame's gain
        else:
            gain = 1.0
        linear = np.ascontiguousarray(linear, np.float32)
        if m.white_e < math.inf:  # shot noise, and read noise (which needs white_e to be measured against)
            out = _adc_to_srgb(self._noisy_codes(linear, frame, stream, gain), linear.shape)
        else:
            out = encode(linear, gain)
        if m.jpeg_quality:
            out = jpeg(out, m.jpeg_quality)
        return out

    def noise(self, frame: int, stream: int = NOISE_STREAM) -> np.ndarray:
        """The frame's standard normals (flat float32, one per pixel and channel): two windows of the episode's bank at
        random offsets keyed by (seed, stream, frame), summed; no frame's noise is a shifted copy of another's."""
        o1, o2 = np.random.default_rng([self.seed, stream, frame]).integers(0, self._bank.size - self._n, 2)
        return cv2.add(self._bank[o1: o1 + self._n], self._bank[o2: o2 + self._n]).ravel()

    def _noisy_codes(self, linear: np.ndarray, frame: int, stream: int, gain: float) -> np.ndarray:
        """Shot + read noise (Gaussian approximation of Poisson, variance = electrons + read²) and the gain, straight
        to the ADC's codes: code = round(g·x + sqrt(g²(x·white_e + read²)) / white_e · z), g = gain × (LINEAR_LEVELS −
        1), in four single-threaded OpenCV passes on float32 (the electrons are never formed: the scale is folded)."""
        m = self.model  # noise needs a finite white_e (SensorModel refuses read noise without one)
        g = float(gain) * (LINEAR_LEVELS - 1)
        c = g / m.white_e  # ADC codes per electron
        flat = linear.reshape(linear.shape[0], -1)  # one channel to OpenCV: its scalars then apply to every element
        sigma = cv2.addWeighted(flat, m.white_e * c * c, flat, 0.0, (m.read_noise_e * c) ** 2)  # variance in codes²
        cv2.sqrt(sigma, sigma)
        cv2.multiply(sigma, self.noise(frame, stream).reshape(flat.shape), sigma)
        return cv2.addWeighted(flat, g, sigma, 1.0, 0.0, dtype=cv2.CV_16U)


def steady_gain(model: SensorModel, linear: np.ndarray) -> float:
    """The auto-exposure gain a still view settles at (its target over the metered luminance, within the range);
    1 without auto-exposure."""
    if model.ae_target <= 0:
        return 1.0
    lo, hi = model.ae_gain_range
    return float(np.clip(model.ae_target / max(_meter(linear), MIN_METERED), lo, hi))


def output_variance(model: SensorModel, linear: np.ndarray, gain: float) -> np.ndarray:
    """Per pixel and channel, the variance (in 8-bit levels²) of the frame the camera delivers for a still view of
    linear radiance `linear`: shot and read noise through the gain and the slope of the sRGB curve, the 12-bit ADC's
    and the 8-bit output's quantisation (uniform, LSB²/12). Saturated pixels carry no information: inf. JPEG is not
    in it (its error depends on the picture: measure it on the frame, `jpeg_variance`)."""
    v = np.asarray(linear, np.float64) * gain
    fw = model.white_e if model.white_e < math.inf else 1.0
    shot = (np.asarray(linear, np.float64) * fw if model.white_e < math.inf else 0.0)
    var_v = gain ** 2 * (shot + model.read_noise_e ** 2) / fw ** 2  # linear units (white = 1), after the gain
    vs = np.clip(v, 1e-6, 1.0)
    slope = 255.0 * np.where(vs <= 0.0031308, 12.92, 1.055 / 2.4 * np.power(vs, 1 / 2.4 - 1))  # levels per unit
    adc = (slope / (LINEAR_LEVELS - 1)) ** 2 / 12.0
    out = slope ** 2 * var_v + adc + 1.0 / 12.0
    return np.where(v >= 1.0, np.inf, out)


def jpeg_variance(frame: np.ndarray, quality: int) -> float:
    """The variance (8-bit levels²) JPEG at `quality` adds to this frame, measured on it; 0 when off."""
    if not quality:
        return 0.0
    return float(np.var(jpeg(frame, quality).astype(np.float64) - frame.astype(np.float64)))


def encode_jpeg(frame: np.ndarray, quality: int) -> np.ndarray:
    """An RGB uint8 frame as JPEG bytes (4:2:0, as cameras and video streams do; OpenCV's libjpeg-turbo)."""
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(frame, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - OpenCV always encodes a valid uint8 image
        raise ConfigError("JPEG encoding failed")
    return buf


def jpeg(frame: np.ndarray, quality: int) -> np.ndarray:
    """Encode and decode an RGB uint8 frame as JPEG (`encode_jpeg`)."""
    # imdecode is None only for bytes that are not an image; encode_jpeg's always are
    return cv2.cvtColor(cv2.imdecode(encode_jpeg(frame, quality), cv2.IMREAD_COLOR),  # type: ignore[arg-type]
                        cv2.COLOR_BGR2RGB)


# ---------------------------------------------------------------- lens distortion


def distort_points(K: np.ndarray, distortion: tuple[float, ...], uv: np.ndarray) -> np.ndarray:
    """Pinhole pixel coordinates (N, 2) → where the distorted lens puts them (OpenCV model)."""
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    if not distortion:
        return uv.copy()
    x = (uv - K[:2, 2]) / np.diag(K)[:2]
    pts = np.column_stack([x, np.ones(len(x))])
    out, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, np.asarray(distortion, np.float64))
    return out.reshape(-1, 2)


def undistort_points(K: np.ndarray, distortion: tuple[float, ...], uv: np.ndarray) -> np.ndarray:
    """Inverse of `distort_points`, solved iteratively to 1e-9 px."""
    uv = np.asarray(uv, np.float64).reshape(-1, 1, 2)
    if not distortion:
        return uv.reshape(-1, 2).copy()
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    out = cv2.undistortPoints(uv, K, np.asarray(distortion, np.float64), None, K, criteria=crit)
    return out.reshape(-1, 2)


def distortion_maps(K: np.ndarray, distortion: tuple[float, ...], width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """cv2.remap maps that turn a pinhole image into the distorted one: output pixel → pinhole source."""
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    src = undistort_points(K, distortion, np.column_stack([xx.ravel(), yy.ravel()]))
    return src[:, 0].reshape(height, width).astype(np.float32), src[:, 1].reshape(height, width).astype(np.float32)
