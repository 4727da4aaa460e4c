"""Checks for settings: one message format naming the setting and what is accepted."""

from __future__ import annotations

import math
import numbers

import numpy as np

from hvs_sim.errors import ConfigError


def check_number(name: str, value, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
                 hi_open: bool = False, integer: bool = False) -> None:
    """Raise ConfigError unless `value` is a finite real (an int when `integer`) within [lo, hi]
    (open at an end when asked). NaN, inf, bools and strings are refused."""
    kind = "an integer" if integer else "a finite number"
    ok_type = isinstance(value, numbers.Integral if integer else numbers.Real) and not isinstance(value, bool)
    ok = ok_type and math.isfinite(float(value))
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value < hi if hi_open else value <= hi
    if not ok:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        rng = f" in {left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}{right}"
        raise ConfigError(f"{name} must be {kind}{rng if (lo is not None or hi is not None) else ''}, got {value!r}")


def check_regular_file(path, what: str, error=ConfigError):
    """A file that will be opened and read whole: refuse, before opening it, what is not a regular file (a FIFO or a
    device would block the read forever, a folder fails it) and a link that loops. Returns it as a Path."""
    import stat
    from pathlib import Path

    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise error(f"{what} {path} does not exist") from None
    except (OSError, RuntimeError) as exc:  # a link loop, a name too long, no permission
        raise error(f"{what} {path} cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    if not stat.S_ISREG(mode):
        kind = ("a named pipe (FIFO)" if stat.S_ISFIFO(mode) else "a folder" if stat.S_ISDIR(mode)
                else "a device or socket")
        raise error(f"{what} {path} is {kind}, not a regular file; give a weights file")
    return path


def check_flags(config, names: tuple[str, ...]) -> None:
    """Each named attribute of `config` is True or False (numpy's bool too): a truthy string such as 'no' would
    otherwise switch a setting on without a word."""
    for name in names:
        value = getattr(config, name)
        if not isinstance(value, (bool, np.bool_)):
            raise ConfigError(f"{name} must be True or False, got {value!r}")
