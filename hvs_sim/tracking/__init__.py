"""Trackers behind one contract: `make_tracker(name)`, `init(frame, roi)`, `update(frame) -> Track`.

Imports nothing from scene/render: outside tools call this on their own image sequences. The names
`make_tracker` accepts (methods and their named variants) are listed once, in registry.py.
"""

from __future__ import annotations

from dataclasses import fields

from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.tracking.base import MODES, Mode, Track, Tracker
from hvs_sim.tracking.registry import METHOD_NAMES, TRACKER_NAMES, TRACKERS, VARIANT_NAMES, TrackerSpec


def _unknown_settings(name: str, unknown, accepted) -> ConfigError:
    return ConfigError(f"{name}: unknown setting(s) {', '.join(sorted(unknown))}; accepted: {', '.join(sorted(accepted))}")


def _settings(name: str, cls, config: dict) -> dict:
    accepted = {f.name for f in fields(cls)}
    unknown = set(config) - accepted
    if unknown:
        raise _unknown_settings(name, unknown, accepted)
    return config


def _lk_from_dict(name: str, config: dict, base) -> dict:
    """`config` with an `lk` given as a dict of LKConfig settings turned into the LKConfig `base` with them
    changed (the tracker's own LK, so {"channels": 16} changes only that)."""
    if not isinstance(config.get("lk"), dict):
        return config
    from dataclasses import replace

    from hvs_sim.tracking.feature_lk import LKConfig

    return {**config, "lk": replace(base, **_settings(f"{name} lk", LKConfig, config["lk"]))}


NESTED_SETTINGS = ("lk", "background_config")  # config fields that are configs themselves, accepted as dicts


def _check_types(name: str, config: dict, classes) -> None:
    """A setting whose default is a number must be given a number (`--set scale=abc` is text): said by name here,
    not as a TypeError where the config compares it."""
    import numbers
    from dataclasses import MISSING

    defaults = {f.name: f.default for cls in classes for f in fields(cls) if f.default is not MISSING}
    for key, value in config.items():
        default = defaults.get(key)
        if isinstance(default, numbers.Real) and not isinstance(default, bool) and default is not None and (
                not isinstance(value, numbers.Real) or isinstance(value, bool)):
            raise ConfigError(f"{name}: {key} must be a number (like its default {default!r}), got {value!r}")


def _builder(name: str, config: dict):
    """The checked configuration of tracker `name` with `config` overriding its settings, as a function
    that builds the tracker (the checks are cheap; building loads weights)."""
    try:
        return _checked_builder(name, config)
    except TypeError as exc:  # a value of a type the config cannot compare: a clear error, not a traceback
        raise ConfigError(f"{name}: a setting has a value of the wrong type ({exc}); give numbers as numbers "
                          "(--set scale=0.5), flags as true/false") from None


def _checked_builder(name: str, config: dict):
    spec: TrackerSpec | None = TRACKERS.get(name)
    if spec is None:
        raise choice_error("tracker", name, TRACKER_NAMES)
    merged = {**spec.config, **config}
    for key in NESTED_SETTINGS:  # nested settings as dicts: the variant's, then the caller's on top, read below
        dicts = [c[key] for c in (spec.config, config) if isinstance(c.get(key), dict)]
        if dicts and isinstance(merged[key], dict):
            merged[key] = {k: v for d in dicts for k, v in d.items()}
    config = merged
    if spec.base in ("deep_lk", "hybrid"):
        from hvs_sim.tracking.deep_lk import DeepLKConfig
        from hvs_sim.tracking.hybrid import HybridConfig

        _check_types(name, config, (DeepLKConfig, HybridConfig) if spec.base == "hybrid" else (DeepLKConfig,))
    if spec.base == "deep_lk":
        from hvs_sim.tracking.deep_lk import DeepLKConfig, DeepLKTracker

        cfg = DeepLKConfig(**_settings(name, DeepLKConfig, _lk_from_dict(name, config, DeepLKConfig().lk)))
        return lambda: DeepLKTracker(cfg)
    if spec.base == "hybrid":
        from hvs_sim.tracking.hybrid import HybridConfig, HybridTracker, hybrid_deep_config

        base_lk = hybrid_deep_config(residual=bool(config.get("residual", False)),
                                     warp=config.get("warp", "similarity")).lk
        if isinstance(config.get("background_config"), dict):  # the surroundings' settings as a dict
            from hvs_sim.tracking.background import BackgroundConfig

            config = {**config, "background_config": BackgroundConfig(
                **_settings(f"{name} background_config", BackgroundConfig, config["background_config"]))}
        cfg = HybridConfig.for_warp(name, **_lk_from_dict(name, config, base_lk))  # checks the settings
        return lambda: HybridTracker(cfg)
    from hvs_sim.tracking.baselines import EccTracker, SiftTracker

    cls = {"sift": SiftTracker, "ecc": EccTracker}[spec.base]
    try:
        tracker = cls(**config)  # cheap: the constructor is the check
    except TypeError:
        import inspect

        accepted = set(inspect.signature(cls).parameters)
        raise _unknown_settings(name, set(config) - accepted, accepted) from None
    return lambda: tracker


def check_tracker(name: str, **config) -> None:
    """Raise the ConfigError `make_tracker(name, **config)` would, without building the tracker."""
    _builder(_check_name(name), config)


def _check_name(name) -> str:
    if not isinstance(name, str):
        raise ConfigError(f"a tracker name must be a string, got {type(name).__name__} {name!r}; accepted: "
                          f"{', '.join(TRACKER_NAMES)}")
    return name


def make_tracker(name: str, *args, **config) -> Tracker:
    """A fresh tracker by name (registry.TRACKERS); keyword arguments override its settings (the
    method's config dataclass fields). Unknown names and settings raise a ConfigError listing the
    accepted ones."""
    if args:
        raise ConfigError(f"make_tracker({name!r}, ...) takes the tracker's settings as keywords (e.g. "
                          f"warp='homography'), got positional {args!r}")
    tracker = _builder(_check_name(name), config)()
    tracker.name = name
    return tracker


__all__ = [
    "METHOD_NAMES",
    "MODES",
    "TRACKERS",
    "TRACKER_NAMES",
    "VARIANT_NAMES",
    "Mode",
    "Track",
    "Tracker",
    "check_tracker",
    "make_tracker",
]
