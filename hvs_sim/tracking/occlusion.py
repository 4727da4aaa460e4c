"""Occlusion estimate OP_t (paper eq. 5–6): share of template pixels that differ by more than τ.

Grey as in the paper, or colour (a pixel differs when any channel does): a brown sleeve over a
red flag has nearly the red's grey level, and grey OP_t then reports a half-covered flag as clear.

Exposure-normalised (a change to the paper, `normalise_exposure`): the paper compares raw
intensities with τ = 30 grey levels, so an auto-exposure step of 25 % alone reads as occlusion of
every bright pixel. An exposure change multiplies the sensor's signal, and after the sRGB curve it
still (nearly) multiplies the encoded value, so the template is first scaled by one gain g: the mode
of the per-pixel log ratios patch / template. The visible part of a target shares one ratio while
an occluder's ratios spread (its values have nothing to do with the template's), so the mode finds
the exposure even when less than half the target shows. When fewer than half the pixels agree with
g, the gain cannot be told from a cover and OP_t is the larger of the normalised and raw values:
the normalisation only ever lowers OP_t where it clearly explains the change.
"""

from __future__ import annotations

import cv2
import numpy as np

from hvs_sim.tracking.warp import warp_image

TAU_PIX = 30  # grey levels
GAIN_RANGE = (0.5, 2.0)  # exposure gains the normalisation may explain
GAIN_MIN_LEVEL = 20  # template pixels darker than this carry too little signal to measure a gain ratio
GAIN_BIN = 0.04  # log-ratio histogram bin (4 % in gain)
MIN_SUPPORT = 0.5  # share of pixels that must agree with the gain for it to be trusted
_LOG_LO, _LOG_HI = np.log(GAIN_RANGE)
_N_BINS = max(1, int(np.ceil((_LOG_HI - _LOG_LO) / GAIN_BIN)))
_EDGES = np.linspace(_LOG_LO, _LOG_HI, _N_BINS + 1)  # the edges np.histogram(bins=_N_BINS, range=…) uses


def _bin_index(r: np.ndarray) -> np.ndarray:
    """The np.histogram(r, bins=_N_BINS, range=(_LOG_LO, _LOG_HI)) bin of each r inside that range,
    without its generic-path overhead: a first guess of each bin, then the same correction against
    the edges that np.histogram makes, so every bin is the one it gives."""
    x = r.astype(np.float64)
    idx = ((x - _LOG_LO) * (_N_BINS / (_LOG_HI - _LOG_LO))).astype(np.intp)
    np.clip(idx, 0, _N_BINS - 1, out=idx)
    idx -= x < _EDGES[idx]
    idx += (x >= _EDGES[idx + 1]) & (idx != _N_BINS - 1)
    return idx


def _log_ratio_counts(r: np.ndarray) -> np.ndarray:
    """np.histogram(r, bins=_N_BINS, range=(_LOG_LO, _LOG_HI))[0] for r inside that range."""
    return np.bincount(_bin_index(r), minlength=_N_BINS)


def _log_ratios(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Per-pixel log ratio patch / template (float32): the gain's evidence (exposure_gain)."""
    return np.log(np.maximum(p.astype(np.float32), 0.5) / t.astype(np.float32))


def _ratio_tables() -> tuple[np.ndarray, np.ndarray]:
    """For every pair of 8-bit values (index 256·p + t): the log ratio, as _log_ratios gives it, and
    its histogram bin (−1 outside GAIN_RANGE or for a template value too dark to carry a ratio).
    Built once: an 8-bit patch then finds both with one lookup per pixel."""
    if not _TABLES:
        v = np.arange(256, dtype=np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = _log_ratios(np.repeat(v, 256), np.tile(v, 256))
        keep = (np.tile(v, 256) > GAIN_MIN_LEVEL) & (r >= _LOG_LO) & (r <= _LOG_HI)
        bins = np.full(r.size, -1, np.intp)
        bins[keep] = _bin_index(r[keep])
        _TABLES.extend([np.where(keep, r, np.float32(0)), bins])
    return _TABLES[0], _TABLES[1]


_TABLES: list[np.ndarray] = []


def aligned_patch(grey: np.ndarray, A: np.ndarray, origin: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Warp the frame into template coordinates. A maps template → frame, origin = template's top-left.

    Returns the patch and a mask of pixels that came from inside the frame.
    """
    T = np.array([[1, 0, origin[0]], [0, 1, origin[1]], [0, 0, 1.0]])
    M = A @ T
    h, w = shape
    patch = warp_image(grey, M, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT)
    if _all_inside(M, (h, w), grey.shape[:2]):  # the common case, without warping a frame-sized mask
        return patch, np.ones((h, w), bool)
    inside = warp_image(np.full(grey.shape[:2], 255, np.uint8), M, (w, h),
                        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT) > 0
    return patch, inside


def _all_inside(M: np.ndarray, shape: tuple[int, int], frame_shape: tuple[int, int]) -> bool:
    """Whether every pixel centre of a (h, w) patch lands inside the frame under M: its four corner
    centres do (the patch is convex, and so is its image under an affine map or a homography that
    keeps all four in front). In Python floats: four 3-vectors cost less than numpy's calls on them."""
    h, w = shape
    H, W = frame_shape
    (a, b, c), (d, e, f), (g, k, m) = M.tolist()
    for u, v in ((0.0, 0.0), (w - 1.0, 0.0), (w - 1.0, h - 1.0), (0.0, h - 1.0)):
        z = g * u + k * v + m
        if z <= 0:
            return False
        x, y = (a * u + b * v + c) / z, (d * u + e * v + f) / z
        if not (0 <= x <= W - 1 and 0 <= y <= H - 1):
            return False
    return True


class OcclusionReference:
    """A template prepared once for OP_t and the exposure gain against many patches: what depends
    on the template alone (its float copy, its bright-enough pixels, their table keys) is done here,
    not on every call. The values are the same as computing everything per call; 8-bit templates and
    patches take the log ratios and their bins from one table lookup (_ratio_tables)."""

    def __init__(self, template: np.ndarray, tau: float = TAU_PIX, normalise_exposure: bool = False):
        self.template, self.tau, self.normalise = template, float(tau), bool(normalise_exposure)
        self.t32 = template.astype(np.float32)
        self.bright = self.t32 > GAIN_MIN_LEVEL
        self.tabled = template.dtype == np.uint8
        if self.tabled:
            self.bright_at = np.flatnonzero(self.bright)  # C order, as boolean indexing takes them
            self.bright_t = template.reshape(-1)[self.bright_at].astype(np.intp)

    def _ratios(self, patch: np.ndarray, inside: np.ndarray | None) -> tuple[np.ndarray, np.ndarray] | None:
        """Log ratios inside GAIN_RANGE over the visible bright-enough pixels, and their bins; None when
        fewer than 16 pixels carry a ratio."""
        visible = inside is None or bool(inside.all())
        if self.tabled and patch.dtype == np.uint8 and visible:
            if self.bright_at.size < 16:
                return None
            ratio, bins = _ratio_tables()
            key = patch.reshape(-1)[self.bright_at].astype(np.intp)
            key *= 256
            key += self.bright_t
            b = bins[key]
            keep = b >= 0
            return ratio[key[keep]], b[keep]
        use = self.bright if visible else self.bright & (inside[..., None] if self.bright.ndim == 3 else inside)
        if np.count_nonzero(use) < 16:
            return None
        r = _log_ratios(patch[use], self.t32[use])
        r = r[(r >= _LOG_LO) & (r <= _LOG_HI)]
        return r, _bin_index(r)

    def gain(self, patch: np.ndarray, inside: np.ndarray | None = None) -> float:
        """One gain g (patch ≈ g · template): the mode of the log ratios over visible, bright-enough
        pixels (module docstring), within GAIN_RANGE; 1 when too few pixels carry a ratio."""
        found = self._ratios(patch, inside)
        if found is None or found[0].size < 16:
            return 1.0
        r, bins = found
        counts = np.bincount(bins, minlength=_N_BINS)
        hist = counts.copy()  # a ratio on a bin edge counts for both sides: counts convolved with [1, 1, 1]
        hist[1:] += counts[:-1]
        hist[:-1] += counts[1:]
        k = int(np.argmax(hist))
        near = r[np.abs(r - 0.5 * (_EDGES[k] + _EDGES[k + 1])) <= 1.5 * GAIN_BIN]
        # np.median's float32 value, and its float32 exp, without np.median's generic-axis overhead
        return float(np.exp(np.float32(median_1d(near)))) if near.size else 1.0

    def _normalised(self, patch: np.ndarray, p32: np.ndarray, inside: np.ndarray | None) -> tuple[float, float]:
        """The exposure gain, and OP_t against the template scaled by it. The gain is trusted where at least
        MIN_SUPPORT of the pixels agree with it (1 − OP_t): over a mostly covered target the mode can be the
        occluder's."""
        g = self.gain(patch, inside)
        return g, self._differs(p32, self.t32 * np.float32(g), inside)

    def trusted_gain(self, patch: np.ndarray, inside: np.ndarray | None = None) -> float:
        """The exposure gain where it is trusted (_normalised), else 1."""
        g, op = self._normalised(patch, patch.astype(np.float32), inside)
        return g if 1.0 - op >= MIN_SUPPORT else 1.0

    def _differs(self, p32: np.ndarray, ref: np.ndarray, inside: np.ndarray | None) -> float:
        diff = np.abs(p32 - ref) > self.tau
        if diff.ndim == 3:  # colour: a pixel differs when any channel does
            diff = diff[..., 0] | diff[..., 1] | diff[..., 2] if diff.shape[2] == 3 else diff.any(axis=2)
        if inside is not None:
            diff |= ~inside
        return np.count_nonzero(diff) / diff.size

    def __call__(self, patch: np.ndarray, inside: np.ndarray | None = None) -> float:
        """OP_t in [0, 1]; pixels that fall outside the frame count as occluded (not visible). With
        `normalise_exposure` the template is scaled by the exposure gain first (module docstring)."""
        p32 = patch.astype(np.float32)
        raw = self._differs(p32, self.t32, inside)
        if not self.normalise:
            return raw
        _, op = self._normalised(patch, p32, inside)
        return op if 1.0 - op >= MIN_SUPPORT else max(op, raw)


def median_1d(r: np.ndarray) -> float:
    """np.median of a 1-D array (the same value), without its generic-axis overhead."""
    h = r.size // 2
    if r.size % 2:
        return float(np.partition(r, h)[h])
    p = np.partition(r, (h - 1, h))
    return float(np.mean(p[h - 1:h + 1]))


def exposure_gain(patch: np.ndarray, template: np.ndarray, inside: np.ndarray | None = None) -> float:
    """OcclusionReference(template).gain(patch, inside), for a template used once."""
    return OcclusionReference(template).gain(patch, inside)


def occlusion_fraction(patch: np.ndarray, template: np.ndarray, inside: np.ndarray | None = None,
                       tau: float = TAU_PIX, normalise_exposure: bool = False) -> float:
    """OP_t of `patch` against `template` (OcclusionReference, for a template used once)."""
    return OcclusionReference(template, tau, normalise_exposure)(patch, inside)
