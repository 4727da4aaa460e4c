"""Outside methods behind hvs_sim's contracts: an outside tracker, servo law or policy wrapped so that its answers are
checked as a built-in's are (a malformed or non-finite answer, or an exception, is a `PluginFault`: the step's fault).

Apart from plugins.py, which finds and builds outside methods by name (registry, entry points, references); this
module is what runs them, step by step.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping

import numpy as np

from hvs_sim.errors import ConfigError, HvsError


class PluginFault(HvsError, ValueError):
    """An outside method's answer was malformed (the loop records it as the step's fault)."""


def _field(out, key, default=None):
    if isinstance(out, Mapping):
        return out.get(key, default)
    return getattr(out, key, default)


CONTRACT_TOL_PX = 0.2  # a first answer this close to the ROI's own corners keeps the contract
CONTRACT_ROUTE = "docs/plugins.md, the corner convention"


class ContractWarning(UserWarning):
    """An outside tracker's first answer looks like another corner convention than hvs_sim's."""


def contract_note(corners: np.ndarray, expected: np.ndarray) -> str | None:
    """Why an outside tracker's answer on its own template frame (where it should give the ROI back) looks like
    another convention: half a pixel off (corners on pixel centres, or (x, y)…(x + w, y + h)), or another order.
    None when it keeps the contract or differs in a way that is not a convention (an honest tracking error)."""
    err = float(np.abs(corners - expected).max())
    if err <= CONTRACT_TOL_PX:
        return None
    for shift in ((0.5, 0.5), (-0.5, -0.5)):
        if np.abs(corners - (expected + shift)).max() <= CONTRACT_TOL_PX:
            return (f"its corners are half a pixel off the ROI it was given ({shift[0]:+.1f}, {shift[1]:+.1f} px): "
                    "hvs_sim's corners are the outer pixel edges, from (x − 0.5, y − 0.5) to (x + w − 0.5, "
                    f"y + h − 0.5) ({CONTRACT_ROUTE})")
    orders = {"counter-clockwise": [0, 3, 2, 1], **{f"starting at corner {k}": list(np.roll(range(4), -k))
                                                   for k in (1, 2, 3)}}
    for name, order in orders.items():
        if np.abs(corners - expected[order]).max() <= CONTRACT_TOL_PX + 0.5:
            return (f"its corners come in another order ({name}): hvs_sim's are top-left, top-right, bottom-right, "
                    f"bottom-left ({CONTRACT_ROUTE})")
    return None


class ExternalTracker:
    """An outside tracker behind hvs_sim's tracker contract: its answers turned into Tracks and checked. Its first
    answer on the frame it was given the ROI on is compared with that ROI (`contract_note`): a tracker written to
    another corner convention is told at step 0, not after a benchmark that failed without a reason."""

    def __init__(self, inner, name: str):
        from hvs_sim.tracking.warp import WARPS

        self.inner, self.name = inner, name
        self.warp = getattr(inner, "warp", "similarity")
        if self.warp not in WARPS:
            raise ConfigError(f"tracker {name!r} declares warp {self.warp!r}; accepted: {', '.join(WARPS)} (which DOFs "
                              "its corners observe)")
        self.can_seed = callable(getattr(inner, "seed", None))
        # the loop's help near the goal (a template grown into the target's plane, given through init and seed) is
        # offered to every tracker with a goal template; one that cannot use it declines by `near_goal = False`
        self.near_goal = bool(getattr(inner, "near_goal", True))
        self.working_scale: float | None = None  # an outside tracker's resolution is its own (Tracker.working_scale)
        self.corners0 = None
        self.contract_note: str | None = None
        self._first, self._frame0 = True, None  # the next answer is the first on the ROI's frame (none seeded since)

    def with_scale(self, scale: float):
        raise ConfigError(f"tracker {self.name!r} is an outside tracker: it has no working scale hvs_sim can change")

    def init(self, frame, roi):
        from hvs_sim.tracking.frames import check_frame, check_roi, roi_corners

        frame = check_frame(frame)
        roi = check_roi(roi, frame.shape[:2])
        self.corners0 = roi_corners(roi)
        t0 = time.perf_counter()
        out = self.inner.init(frame, roi)
        self._first, self._frame0 = True, frame
        return None if out is None else self._checked(self._track(out, 1e3 * (time.perf_counter() - t0)))

    def seed(self, A) -> None:
        if not self.can_seed:
            raise ConfigError(f"tracker {self.name!r} has no seed(A): it cannot take a template from the goal image; "
                              "use template_from='start'")
        self._first = False  # later answers are on other frames, at seeded corners
        self.inner.seed(np.asarray(A, float))

    def update(self, frame):
        t0 = time.perf_counter()
        out = self.inner.update(frame)
        track = self._track(out, 1e3 * (time.perf_counter() - t0))
        if self._first and not (frame is self._frame0 or np.array_equal(frame, self._frame0)):
            self._first = False  # the first update is on another frame: the ROI is no longer its answer
        return self._checked(track)

    def _checked(self, track):
        """The first answer after init, compared with the ROI (the loop's step 0 gives the init frame again)."""
        if self._first:
            self._first = False
            note = contract_note(track.corners, self.corners0)
            if note is not None and self.contract_note is None:
                self.contract_note = f"tracker {self.name!r}: {note}"
                warnings.warn(self.contract_note, ContractWarning, stacklevel=3)
        return track

    def _track(self, out, ms: float):
        from hvs_sim.tracking.base import MODES, Track
        from hvs_sim.tracking.warp import fit_similarity, matrix_to_pose

        who = f"tracker {self.name!r}"
        if out is None:
            raise PluginFault(f"{who} returned None; accepted: a Track or an object/mapping with corners (4×2 pixels)")
        try:
            corners = np.asarray(_field(out, "corners"), float)
        except (TypeError, ValueError):
            corners = np.zeros(0)
        if corners.shape != (4, 2) or not np.all(np.isfinite(corners)):
            raise PluginFault(f"{who} returned corners of shape {corners.shape}"
                              + ("" if corners.shape != (4, 2) else " with non-finite values")
                              + "; accepted: 4×2 finite pixels")
        center = _field(out, "center")
        try:
            center = corners.mean(0) if center is None else np.asarray(center, float).reshape(-1)
        except (TypeError, ValueError):
            center = np.full(1, np.nan)
        mode = str(_field(out, "mode", "align"))
        values = {k: _field(out, k, d) for k, d in (("occlusion", 0.0), ("score", 1.0), ("confidence", 1.0))}
        if center.shape != (2,) or not np.all(np.isfinite(center)):
            raise PluginFault(f"{who} returned a centre {center.tolist()}; accepted: 2 finite pixels")
        if mode not in MODES:
            raise PluginFault(f"{who} returned mode {mode!r}; accepted: {', '.join(MODES)}")
        for k, v in values.items():
            try:
                v = float(v)
            except (TypeError, ValueError):
                v = float("nan")
            if not (np.isfinite(v) and (k == "score" or 0.0 <= v <= 1.0)):
                raise PluginFault(f"{who} returned {k} {values[k]!r}; accepted: a finite number"
                                  + ("" if k == "score" else " in [0, 1]"))
            values[k] = v
        pose = matrix_to_pose(fit_similarity(self.corners0, corners), self.corners0.mean(0))
        return Track(center=center, corners=corners, pose=pose, mode=mode, occlusion=values["occlusion"],
                     score=values["score"], ms=ms, confidence=values["confidence"])


class ExternalController:
    """An outside servo law: compute(ControlInput) checked to a finite 6-vector and valid DOFs."""

    def __init__(self, inner, name: str):
        from hvs_sim.control.protocol import check_dofs

        self.inner, self.name = inner, name
        dofs = getattr(inner, "dofs", None)
        try:
            self.dofs = None if dofs is None else check_dofs(dofs, f"controller {name!r}")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self.uses_features = bool(getattr(inner, "uses_features", True))

    def compute(self, inp):
        from hvs_sim.control.protocol import check_dofs, check_twist

        who = f"controller {self.name!r}"
        out = self.inner.compute(inp)
        twist = check_twist(out, who)
        dofs = getattr(out, "dofs", None) or self.dofs
        return twist, None if dofs is None else check_dofs(dofs, who)


class ExternalPolicy:
    """An outside policy: act(PolicyInput) checked to a finite 6-vector."""

    def __init__(self, inner, name: str):
        from hvs_sim.control.protocol import DOF_NAMES, check_dofs

        self.inner, self.name = inner, name
        try:
            self.dofs = check_dofs(getattr(inner, "dofs", DOF_NAMES), f"policy {name!r}")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None

    def reset(self, obs) -> None:
        if callable(getattr(self.inner, "reset", None)):
            self.inner.reset(obs)

    def act(self, obs) -> np.ndarray:
        from hvs_sim.control.protocol import check_twist

        return check_twist(self.inner.act(obs), f"policy {self.name!r}")
