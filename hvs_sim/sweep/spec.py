"""A sweep's spec: the TOML it is written in, every key it may name and what each accepts, the grid of tasks it makes
and their stable ids. Nothing here runs a task."""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import tomllib
from pathlib import Path

import numpy as np

from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.validate import check_number

KINDS = ("track", "servo")
# metrics that measure time: they differ between runs and engines; every other metric is seeded
TIMING_METRICS = ("median_ms", "p95_ms", "steps_per_second", "task_seconds")


def _loop_fields() -> dict[str, str]:
    """Servo settings a sweep may vary: IBVSConfig fields ("ibvs-field") and LoopConfig fields ("loop-field")."""
    from hvs_sim.control.laws.ibvs import IBVSConfig
    from hvs_sim.servo.config import LoopConfig

    ibvs = {f.name: "ibvs-field" for f in dataclasses.fields(IBVSConfig)}
    loop = {f.name: "loop-field" for f in dataclasses.fields(LoopConfig) if f.name not in ("ibvs", "steps", "keep_frames")}
    return {**ibvs, **loop}


def _common_keys() -> dict[str, object]:
    from hvs_sim.scene.scenarios import PEOPLE_STYLES, SCENARIO_NAMES
    from hvs_sim.sensor import SENSOR_NAMES

    return {"tracker": None, "scenario": SCENARIO_NAMES, "camera": SENSOR_NAMES, "people": PEOPLE_STYLES,
            "seed": "int>=0", "width": "image", "height": "image"}


def accepted_keys(kind: str) -> dict[str, object]:
    """Every key a spec of this kind may name in [axes] or [fixed], with what it accepts."""
    from hvs_sim.scene.scenarios import MOUNTS
    from hvs_sim.servo.config import LOOP_TRACKERS
    from hvs_sim.tracking import TRACKER_NAMES

    keys = _common_keys()
    if kind == "track":
        keys.update(tracker=TRACKER_NAMES, mount=MOUNTS, frames="int>=2")
    else:
        from hvs_sim.scene.arms import ARM_NAMES

        keys.update(tracker=LOOP_TRACKERS, steps="int>=1", arm=ARM_NAMES, **_loop_fields())
    return keys


DEFAULTS = {"track": {"tracker": "hybrid", "scenario": "walk_by", "camera": "phone_handheld", "people": "textured",
                      "seed": 100, "width": 640, "height": 480, "mount": "handheld", "frames": None},
            "servo": {"tracker": "hybrid", "scenario": "walk_by", "camera": "phone_handheld", "people": "textured",
                      "seed": 200, "width": 640, "height": 480, "steps": None}}


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    kind: str
    axes: dict  # key -> list of values
    fixed: dict  # key -> value

    def tasks(self) -> list[dict]:
        """The grid: one parameter dict per cell (defaults, then fixed, then this cell's axis values)."""
        names = list(self.axes)
        cells = itertools.product(*(self.axes[n] for n in names))
        base = {**{k: v for k, v in DEFAULTS[self.kind].items() if v is not None}, **self.fixed}
        return [{**base, **dict(zip(names, cell))} for cell in cells]


def _check_value(kind: str, key: str, value, accepted) -> None:
    if accepted == "int>=0":
        check_number(key, value, 0, integer=True)
    elif accepted == "int>=1":
        check_number(key, value, 1, integer=True)
    elif accepted == "int>=2":
        check_number(key, value, 2, integer=True)
    elif accepted == "image":
        check_number(key, value, 64, 4096, integer=True)
    elif accepted in ("ibvs-field", "loop-field"):
        from hvs_sim.control.laws.ibvs import IBVSConfig
        from hvs_sim.servo.config import LoopConfig

        try:
            (IBVSConfig if accepted == "ibvs-field" else LoopConfig)(**{key: tuple(value) if isinstance(value, list) else value})
        except TypeError as exc:
            raise ConfigError(f"{key}: {exc}") from None
    elif key == "tracker" and value not in accepted:  # an outside tracker (hvs_sim.plugins)
        from hvs_sim.plugins import check, check_any_tracker

        if kind == "track":
            check_any_tracker(value)
        else:
            check("tracker", value)
    elif value not in accepted:
        raise choice_error(key, value, accepted)


def parse_spec(text: str, source: str = "spec") -> SweepSpec:
    """Validate a TOML sweep spec; every error names the bad key and what is accepted."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML ({exc})") from None
    unknown = set(data) - {"kind", "axes", "fixed"}
    if unknown:
        raise ConfigError(f"{source}: unknown top-level keys {sorted(unknown)}; accepted: kind, axes, fixed")
    kind = data.get("kind")
    if kind not in KINDS:
        raise choice_error("sweep kind", kind, KINDS)
    axes, fixed = data.get("axes", {}), data.get("fixed", {})
    if not isinstance(axes, dict) or not isinstance(fixed, dict) or not axes:
        raise ConfigError(f"{source}: [axes] must be a table with at least one key (and [fixed] a table)")
    accepted = accepted_keys(kind)
    for key in (*axes, *fixed):
        if key not in accepted:
            raise ConfigError(f"{source}: unknown key {key!r} for a {kind} sweep; accepted: {', '.join(accepted)}")
    both = set(axes) & set(fixed)
    if both:
        raise ConfigError(f"{source}: {sorted(both)} are in both [axes] and [fixed]; give each once")
    for key, values in axes.items():
        if not isinstance(values, list) or not values:
            raise ConfigError(f"{source}: axis {key!r} must be a non-empty list, got {values!r}")
        if len({json.dumps(_same_number(v), default=str) for v in values}) != len(values):  # 2 and 2.0: one cell
            raise ConfigError(f"{source}: axis {key!r} repeats a value: {values}")
        for v in values:
            _check_value(kind, key, v, accepted[key])
    for key, v in fixed.items():
        _check_value(kind, key, v, accepted[key])
    return SweepSpec(kind, axes, fixed)


def _same_number(v):
    """2 and 2.0 as one value (a grid cell run twice otherwise); bools and the rest as they are."""
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v


def grid_size(spec: SweepSpec) -> int:
    """The number of tasks, without building the grid."""
    return int(np.prod([len(v) for v in spec.axes.values()], dtype=object))


def spec_hash(spec: SweepSpec) -> str:
    return hashlib.sha1(json.dumps(dataclasses.asdict(spec), sort_keys=True).encode()).hexdigest()[:16]


def load_spec(path) -> SweepSpec:
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"sweep spec {path} not found (a TOML file: kind, [axes], [fixed])")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read sweep spec {path}: {exc}") from None
    return parse_spec(text, str(path))


def task_id(kind: str, params: dict) -> str:
    """Stable id of a task: a hash of its kind and parameters (the name of its result file)."""
    return hashlib.sha1(json.dumps({"kind": kind, **params}, sort_keys=True).encode()).hexdigest()[:16]
