"""Global template search: normalised cross-correlation over the whole frame (paper eq. 7–8).

Coarse-to-fine: the whole frame is searched at 1/`coarse` resolution, then the peak is refined at
full working resolution in a small window, so a lost target is found anywhere in the frame at a
fraction of the cost of a full-resolution search. The peak score is the match confidence.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from hvs_sim.errors import ConfigError


@dataclass(frozen=True)
class Match:
    center: np.ndarray  # (x, y) of the template centre, frame pixels (sub-pixel)
    score: float  # peak NCC in [-1, 1]; 0 for a blank frame
    # best NCC away from the peak (further than half the template's smaller side, on the coarse
    # search): how unique the match is; a self-similar texture (fur, gravel) has second ≈ score, and so
    # has a weakly textured target along its own direction (a kerb, a road line: its look-alike lies
    # less than a template's side along it)
    second: float = -1.0


@dataclass
class SearchImage:
    """A grey frame prepared once for several searches in it (the hybrid searches with the rectified
    template and with the template as taken): its spread and its coarse copy are computed once."""

    grey: np.ndarray
    std: float
    small: dict[int, np.ndarray] = field(default_factory=dict)  # coarse factor → resized frame

    def coarse(self, f: int) -> np.ndarray:
        if f not in self.small:
            self.small[f] = cv2.resize(self.grey, None, fx=1 / f, fy=1 / f, interpolation=cv2.INTER_AREA)
        return self.small[f]


def _std(image: np.ndarray) -> float:
    """Population standard deviation (cv2.meanStdDev: one pass, no float64 copy as np.std makes)."""
    return float(cv2.meanStdDev(image)[1][0, 0])


def _subpixel(resp: np.ndarray, x: int, y: int) -> tuple[float, float]:
    def para(m1, c, p1):
        d = m1 - 2 * c + p1
        return 0.0 if abs(d) < 1e-12 else float(np.clip(0.5 * (m1 - p1) / d, -0.5, 0.5))

    dx = para(resp[y, x - 1], resp[y, x], resp[y, x + 1]) if 0 < x < resp.shape[1] - 1 else 0.0
    dy = para(resp[y - 1, x], resp[y, x], resp[y + 1, x]) if 0 < y < resp.shape[0] - 1 else 0.0
    return x + dx, y + dy


def _second_peak(resp: np.ndarray, x: int, y: int, radius: int) -> float:
    """Highest response further than `radius` from the peak at (x, y)."""
    masked = resp.copy()
    r = max(radius, 1)
    masked[max(0, y - r):y + r + 1, max(0, x - r):x + r + 1] = -1.0
    return float(masked.max()) if masked.size else -1.0


class GlobalMatcher:
    """NCC search of a (rectified) grey template over a grey frame."""

    def __init__(self, coarse: int = 2, window: int = 6):
        if coarse not in (1, 2, 4):
            raise ConfigError(f"coarse factor must be 1, 2 or 4, got {coarse}")
        self.coarse, self.window = coarse, window

    def prepare(self, grey: np.ndarray) -> SearchImage:
        """`grey` ready for several `match` calls (each reuses its spread and coarse copy)."""
        return SearchImage(grey, _std(grey))

    def match(self, grey: np.ndarray | SearchImage, template: np.ndarray) -> Match:
        search = grey if isinstance(grey, SearchImage) else self.prepare(grey)
        grey = search.grey
        th, tw = template.shape
        if _std(template) < 1e-3 or search.std < 1e-3:
            return Match(center=np.array([np.nan, np.nan]), score=0.0)
        f = self.coarse
        if f > 1 and min(th, tw) // f >= 8:
            small = search.coarse(f)
            tsmall = cv2.resize(template, None, fx=1 / f, fy=1 / f, interpolation=cv2.INTER_AREA)
            resp = np.nan_to_num(cv2.matchTemplate(small, tsmall, cv2.TM_CCOEFF_NORMED), nan=-1.0)
            _, _, _, (x, y) = cv2.minMaxLoc(resp)
            second = _second_peak(resp, x, y, min(tsmall.shape) // 2)
            # top-left corner at full working resolution, then a local search around it
            x0, y0 = round((x + 0.5) * f - 0.5), round((y + 0.5) * f - 0.5)
            center, score, _ = self._search_window(grey, template, x0, y0, self.window + f)
            return Match(center=center, score=score, second=float(second))
        resp = np.nan_to_num(cv2.matchTemplate(grey, template, cv2.TM_CCOEFF_NORMED), nan=-1.0)
        _, score, _, (x, y) = cv2.minMaxLoc(resp)
        second = _second_peak(resp, x, y, min(th, tw) // 2)
        sx, sy = _subpixel(resp, x, y)
        center = np.array([sx + (tw - 1) / 2.0, sy + (th - 1) / 2.0])
        return Match(center=center, score=float(score), second=float(second))

    def match_near(self, grey: np.ndarray | SearchImage, template: np.ndarray, center: np.ndarray) -> Match | None:
        """The match within `window` px of `center` (the template's centre, frame pixels), at full working
        resolution: what `match` finds there when its peak is near `center`, at the cost of its last step
        only. None when the best place is on the window's edge (the peak lies outside it) or the window
        leaves the frame. `second` is not measured (−1): nothing outside the window was searched."""
        search = grey if isinstance(grey, SearchImage) else self.prepare(grey)
        th, tw = template.shape
        if _std(template) < 1e-3 or search.std < 1e-3 or not np.all(np.isfinite(center)):
            return None
        x0, y0 = round(center[0] - (tw - 1) / 2.0), round(center[1] - (th - 1) / 2.0)
        found, score, interior = self._search_window(search.grey, template, x0, y0, self.window)
        return Match(center=found, score=score) if interior else None

    @staticmethod
    def _search_window(grey: np.ndarray, template: np.ndarray, x0: int, y0: int, r: int
                       ) -> tuple[np.ndarray, float, bool]:
        """NCC of the template with its top-left corner within r px of (x0, y0): the sub-pixel centre of the
        best place, its score, and whether that place has a searched neighbour on every side."""
        th, tw = template.shape
        xa, ya = max(0, x0 - r), max(0, y0 - r)
        xb, yb = min(grey.shape[1] - tw, x0 + r), min(grey.shape[0] - th, y0 + r)
        if xb < xa or yb < ya:
            return np.array([np.nan, np.nan]), -1.0, False
        resp = np.nan_to_num(cv2.matchTemplate(grey[ya:yb + th, xa:xb + tw], template, cv2.TM_CCOEFF_NORMED), nan=-1.0)
        _, score, _, (x, y) = cv2.minMaxLoc(resp)
        interior = 0 < x < resp.shape[1] - 1 and 0 < y < resp.shape[0] - 1
        sx, sy = _subpixel(resp, x, y)
        return np.array([xa + sx + (tw - 1) / 2.0, ya + sy + (th - 1) / 2.0]), float(score), interior
