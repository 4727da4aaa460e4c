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


def arg_type(parse):
    """An option's parser whose ValueError argparse reports with its own message (not "invalid value")."""
    def typed(text: str):
        try:
            return parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    typed.__name__ = getattr(parse, "__name__", "value")
    return typed


def near_goal_inset(text: str) -> int | str:
    """--near-goal-inset's value: auto, off, or a whole number of px (LoopConfig.near_goal_inset_px checks it)."""
    from hvs_sim.servo.config import parse_near_goal_inset

    return arg_type(parse_near_goal_inset)(text)


def add_config_options(p: argparse.ArgumentParser, options: list[tuple[str, dict]], help_prefix: str = "") -> None:
    """Each config field's option (servo.config.loop_options: its flag, help and argparse keywords) under the field's
    own name, default None: a field the user did not give keeps the config's default (`given_options`)."""
    for name, cli in options:
        kw = {k: v for k, v in cli.items() if k not in ("flag", "help")}
        if callable(kw.get("type")) and kw["type"] not in (int, float, str):
            kw["type"] = arg_type(kw["type"])
        p.add_argument(cli["flag"], dest=name, default=None, help=help_prefix + cli["help"], **kw)


def given_options(args: argparse.Namespace, options: list[tuple[str, dict]]) -> dict:
    """The config fields the user gave on the command line (`add_config_options`), by field name."""
    return {name: getattr(args, name) for name, _ in options if getattr(args, name, None) is not None}


def option_flags(args: argparse.Namespace, options: list[tuple[str, dict]]) -> list[tuple[str, object]]:
    """(flag, value) of each of these options, as the user spelled the flag (for "--x applies to ... only")."""
    return [(cli["flag"], getattr(args, name, None)) for name, cli in options]


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
