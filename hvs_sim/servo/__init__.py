"""The closed loop, in parts: `config` (LoopConfig), `plan` (the rules and the settings resolved once), `teach` (goal
image, template box, near-goal growth), `parts` (what a step carries), `records` (StepRecord, RunStats) and `loop`
(ServoLoop, the episode's steps). The names a user reaches for load on first use: `import hvs_sim.servo` stays
cheap."""

from __future__ import annotations

import importlib

_WHERE = {"LoopConfig": "config", "ServoLoop": "loop", "StepRecord": "records", "RunStats": "records",
          "summarize_run": "records", "MODES": "records"}
__all__ = ["MODES", "LoopConfig", "RunStats", "ServoLoop", "StepRecord", "summarize_run"]


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(f"hvs_sim.servo.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'hvs_sim.servo' has no attribute {name!r}")
