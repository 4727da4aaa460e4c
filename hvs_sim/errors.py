"""One error family for hvs_sim: every bad input raises an `HvsError` that names what is accepted."""

from __future__ import annotations


class HvsError(Exception):
    """Base of every error hvs_sim raises on purpose."""


class ConfigError(HvsError, ValueError):
    """A setting, name or parameter is outside what is accepted."""


class InputError(HvsError, ValueError):
    """A frame, ROI or array handed to hvs_sim does not have the accepted type, shape or values."""


class StateError(HvsError, RuntimeError):
    """A call came in the wrong order (e.g. `update` before `init`)."""


class RenderError(HvsError, RuntimeError):
    """No headless OpenGL back-end could be started."""


class OutputError(HvsError, OSError):
    """An output could not be written (a full disk, a folder gone); the file it would have replaced is kept."""


class WeightsError(HvsError, RuntimeError):
    """A weights file is missing, corrupt or does not match the network."""


def choice_error(what: str, value: object, accepted) -> ConfigError:
    """Build the standard 'unknown X' error listing the accepted values."""
    return ConfigError(f"unknown {what} {value!r}; accepted: {', '.join(map(str, accepted))}")
