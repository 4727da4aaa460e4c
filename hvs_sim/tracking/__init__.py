"""Trackers behind one contract: `make_tracker(name)`, `init(frame, roi)`, `update(frame) -> Track`.

Imports nothing from scene/render: outside tools call this on their own image sequences.
"""

from __future__ import annotations

from dataclasses import fields

from hvs_sim.errors import choice_error
from hvs_sim.tracking.base import MODES, Track, Tracker

TRACKER_NAMES = ("sift", "ecc", "deep_lk", "deep_lk_residual", "hybrid")


def make_tracker(name: str, **config) -> Tracker:
    """A fresh tracker by name; keyword arguments go to the method's config dataclass."""
    if name in ("deep_lk", "deep_lk_residual"):
        from hvs_sim.tracking.deep_lk import DeepLKConfig, DeepLKTracker

        tracker = DeepLKTracker(DeepLKConfig(**{"residual": name == "deep_lk_residual", **config}))
        tracker.name = name
        return tracker
    if name == "hybrid":
        from hvs_sim.tracking.deep_lk import DeepLKConfig
        from hvs_sim.tracking.hybrid import HybridConfig, HybridTracker

        hybrid_keys = {f.name for f in fields(HybridConfig)} - {"deep"}
        deep = DeepLKConfig(**{"residual": True, **{k: v for k, v in config.items() if k not in hybrid_keys}})
        return HybridTracker(HybridConfig(deep=deep, **{k: v for k, v in config.items() if k in hybrid_keys}))
    if name == "sift":
        from hvs_sim.tracking.baselines import SiftTracker

        return SiftTracker(**config)
    if name == "ecc":
        from hvs_sim.tracking.baselines import EccTracker

        return EccTracker(**config)
    raise choice_error("tracker", name, TRACKER_NAMES)


__all__ = ["make_tracker", "Track", "Tracker", "MODES", "TRACKER_NAMES"]
