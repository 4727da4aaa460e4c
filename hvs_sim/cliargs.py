"""Command-line helpers the commands share (`hvs-sim run`, `track`, ...): the default tracker and `--set KEY=VALUE`.

A module of its own so that command modules (the cli package, video.py) import it, and not each other.
"""

from __future__ import annotations

import argparse
import json

from hvs_sim.errors import ConfigError

DEFAULT_TRACKER = "hybrid"


def add_settings_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a tracker setting (a field of its config; repeat for more), e.g. --set "
                        "residual_weights=out/weights/residual.pt --set gru_weights=out/weights/gru.pt; an unknown "
                        "key is an error that lists the accepted ones")


def near_goal_inset(text: str) -> int | str:
    """--near-goal-inset's value: auto, off, or a whole number of px (LoopConfig.near_goal_inset_px checks it)."""
    if text in ("auto", "off"):
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected auto, off or a negative whole number of px, got {text!r}") from None


def parse_settings(items: list[str]) -> dict:
    """KEY=VALUE strings → make_tracker keywords; VALUE is read as JSON (numbers, true/false, null) or else text."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set takes KEY=VALUE, got {item!r}")
        try:
            out[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            out[key.strip()] = value
    return out
