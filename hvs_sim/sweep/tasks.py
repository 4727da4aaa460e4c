"""One sweep task: its scenario and settings made from its parameters, run to a record that never raises, and that
record read back and checked (a damaged one is re-run). What runs in a worker process or on a Ray node."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

from hvs_sim.bench.servo import EXTRA_STEPS, SUCCESS_PX
from hvs_sim.bench.stats import episode_success
from hvs_sim.errors import ConfigError
from hvs_sim.sweep.spec import SweepSpec, _loop_fields


def _scenario(params: dict, mount: str):
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    cam = CameraConfig(width=params["width"], height=params["height"], sensor=params["camera"])
    if mount == "arm":  # the start pose as the servo benchmark draws it (reachable, target in view)
        from hvs_sim.bench.servo import episode_scenario

        return episode_scenario(params["scenario"], params["seed"], camera=cam, people=params["people"],
                                arm=params.get("arm", "jaco"))  # no default in DEFAULTS: earlier task ids stay
    return make_scenario(params["scenario"], mount=mount, seed=params["seed"], camera=cam, people=params["people"])


def _track_task(params: dict) -> dict:
    from hvs_sim.bench.sequences import make_sequence
    from hvs_sim.bench.track import run_tracker, summarize

    seq = make_sequence(_scenario(params, params["mount"]), n_frames=params.get("frames"))
    r = run_tracker(params["tracker"], seq)
    visible = summarize([r], lambda x: x["occlusion"] < 0.4)
    metrics = summarize([r])
    metrics["frames_scored"] = metrics.pop("frames")  # `frames` is the task parameter
    return {**metrics, "visible_pct_le_2px": visible.get("pct_le_2px"),
            "errors": [round(float(e), 4) for e in r["error"][1:]]}


def _loop_config(params: dict):
    """The LoopConfig a servo task's parameters make (steps left to the task)."""
    from hvs_sim.control.laws.ibvs import IBVSConfig
    from hvs_sim.servo.config import LoopConfig

    fields = _loop_fields()
    ibvs = IBVSConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in params.items()
                         if fields.get(k) == "ibvs-field"})
    loop = {k: v for k, v in params.items() if fields.get(k) == "loop-field"}
    return LoopConfig(ibvs=ibvs, keep_frames=False, **loop)


def check_grid(spec: SweepSpec) -> None:
    """A servo grid's cells checked together before anything runs: the settings of one cell that conflict (a goal
    image with a start template, a policy beside a law, features to filter from the oracle) are refused with the
    cell, instead of failing as a task."""
    if spec.kind != "servo":
        return
    from hvs_sim.servo.plan import check_combination

    seen = set()
    for params in spec.tasks():
        key = json.dumps({k: v for k, v in params.items() if k not in ("seed", "scenario")}, sort_keys=True)
        if key in seen:
            continue
        seen.add(key)
        try:
            check_combination(params["tracker"], _loop_config(params))
        except (ConfigError, TypeError) as exc:
            cell = {k: v for k, v in params.items() if k in spec.axes}
            raise ConfigError(f"the grid cell {cell} cannot run: {exc}") from None


def _servo_task(params: dict) -> dict:
    from hvs_sim.runner import run_episode

    scen = _scenario(params, "arm")
    steps = params.get("steps") or scen.n_frames + EXTRA_STEPS
    summary, _ = run_episode(scen, params["tracker"], dataclasses.replace(_loop_config(params), steps=steps),
                             progress=False)
    keys = ("converged", "held_to_end", "steps_to_converge", "seconds_to_converge", "final_error_px",
            "final_pose_error_mm", "final_pose_error_deg", "max_error_px_during_occlusion", "lost_steps",
            "predict_steps", "fault_steps", "steps_per_second")
    out = {k: summary.get(k) for k in keys}
    # the servo benchmark's rules (bench/stats.py): hvs_sim's is `success`
    verdicts = episode_success(summary, SUCCESS_PX)
    out["success"] = verdicts.pop("hvs_sim")
    out.update({f"success_{rule}": v for rule, v in verdicts.items()})
    return out


def run_task(job: tuple[str, str, dict]) -> dict:
    """One task, never raising: its metrics, or its error. One torch thread, so a task gives the
    same numbers on any engine and any number of workers."""
    import torch

    kind, tid, params, *run_as = job  # run_as: the parameters with methods spelled for this process (_portable)
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    record = {"id": tid, "kind": kind, "params": params}
    try:
        record.update(status="ok", metrics=(_track_task if kind == "track" else _servo_task)(run_as[0] if run_as
                                                                                            else params))
    except Exception as exc:  # noqa: BLE001 - a failing task is recorded and the sweep goes on
        record.update(status="error", error=f"{type(exc).__name__}: {exc}")
    record["task_seconds"] = round(time.perf_counter() - t0, 3)
    return record


def _task_state(path: Path) -> str:
    """"ok", "error" (a failed task, retried on re-run), "corrupt" (unreadable: set aside and re-run) or "missing"."""
    if not path.exists():
        return "missing"
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return "corrupt"
    if not isinstance(record, dict) or not {"id", "params", "status"} <= set(record) \
            or not isinstance(record["params"], dict):
        return "corrupt"
    if record["status"] == "ok":
        return "ok" if _metrics_ok(record.get("metrics")) else "corrupt"
    return "error"


def _number(v) -> bool:
    return isinstance(v, (int, float))  # bool is an int: a verdict such as `success`


def _metrics_ok(metrics) -> bool:
    """A done task's metrics as run_task writes them: numbers, verdicts or null, and a track task's per-frame
    `errors` a list of numbers. Anything else (a string "NaN", a list where a number goes) is a damaged record."""
    if not isinstance(metrics, dict):
        return False
    for key, value in metrics.items():
        if key == "errors":
            if not (isinstance(value, list) and all(_number(e) for e in value)):
                return False
        elif value is not None and not _number(value):
            return False
    return True
