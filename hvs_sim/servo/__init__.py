"""The closed loop, in parts: `config` (LoopConfig), `plan` (the rules and the settings resolved once), `teach` (goal
image, template box, near-goal growth), `parts` (what a step carries; Observation, Truth), `task` (ServoTask, the world
the loop and the gym env step), `templates` (the start and near-goal templates), `step` (one step, its two drivers),
`tracked` (a tracker's corners as an observation), `laws` (what each law uses, the law on a template), `records`
(StepRecord, RunStats) and `loop` (ServoLoop, the agent). The names a user reaches for load on first use: `import
hvs_sim.servo` stays cheap."""

from __future__ import annotations

import importlib

_WHERE = {"LoopConfig": "config", "ServoLoop": "loop", "StepRecord": "records", "RunStats": "records",
          "summarize_run": "records", "MODES": "records", "ServoTask": "task", "Observation": "parts", "Truth": "parts"}
__all__ = ["MODES", "LoopConfig", "Observation", "RunStats", "ServoLoop", "ServoTask", "StepRecord", "Truth",
           "summarize_run"]


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(f"hvs_sim.servo.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'hvs_sim.servo' has no attribute {name!r}")
