"""Parameter sweeps: a TOML spec names axes, the grid is their product, each cell an independent task.

    kind = "servo"                       # or "track" (open-loop tracking accuracy)
    [axes]                               # lists; the grid is their product
    tracker = ["hybrid", "deep_lk"]
    scenario = ["walk_by", "pause"]
    seed = [200, 201, 202]
    gain = [1.0, 2.0]                    # servo: any IBVSConfig or LoopConfig field
    [fixed]                              # one value each, the same for every task (optional)
    camera = "phone_handheld"

Tasks run on a local process pool (the benchmarks' bench/pool.py) or on Ray (one CPU per task,
one torch thread, a local instance or an existing cluster). Each finished task is written
atomically to DIR/tasks/<id>.json, its id a hash of its parameters, so re-running a spec skips
what is done and an interrupted sweep loses only the tasks in flight. A task that raises is
recorded with its error and the sweep goes on. DIR/results.csv holds every task of the spec.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import itertools
import json
import os
import time
import tomllib
from pathlib import Path

import numpy as np

from hvs_sim.bench.servo import EXTRA_STEPS, SUCCESS_PX
from hvs_sim.bench.stats import episode_success
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.validate import check_number

KINDS = ("track", "servo")
ENGINES = ("local", "ray")
MAX_TASKS = 10_000  # a grid larger than this is refused before anything is built (run_sweep's max_tasks overrides)
LOCK_NAME = ".sweep.lock"  # held by the one sweep that writes a folder (fcntl.flock; released when the process ends)
# metrics that measure time: they differ between runs and engines; every other metric is seeded
TIMING_METRICS = ("median_ms", "p95_ms", "steps_per_second", "task_seconds")


def _loop_fields() -> dict[str, str]:
    """Servo settings a sweep may vary: IBVSConfig fields ("ibvs-field") and LoopConfig fields ("loop-field")."""
    from hvs_sim.control.ibvs import IBVSConfig
    from hvs_sim.loop import LoopConfig

    ibvs = {f.name: "ibvs-field" for f in dataclasses.fields(IBVSConfig)}
    loop = {f.name: "loop-field" for f in dataclasses.fields(LoopConfig) if f.name not in ("ibvs", "steps", "keep_frames")}
    return {**ibvs, **loop}


def _common_keys() -> dict[str, object]:
    from hvs_sim.camera_model import SENSOR_NAMES
    from hvs_sim.scene.scenarios import PEOPLE_STYLES, SCENARIO_NAMES

    return {"tracker": None, "scenario": SCENARIO_NAMES, "camera": SENSOR_NAMES, "people": PEOPLE_STYLES,
            "seed": "int>=0", "width": "image", "height": "image"}


def accepted_keys(kind: str) -> dict[str, object]:
    """Every key a spec of this kind may name in [axes] or [fixed], with what it accepts."""
    from hvs_sim.loop import LOOP_TRACKERS
    from hvs_sim.scene.scenarios import MOUNTS
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
        from hvs_sim.control.ibvs import IBVSConfig
        from hvs_sim.loop import LoopConfig

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


# ------------------------------------------------------------------------------------ tasks


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
    from hvs_sim.control.ibvs import IBVSConfig
    from hvs_sim.loop import LoopConfig

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
    from hvs_sim.loop import check_combination

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


# ------------------------------------------------------------------------------------ engines


def _portable(params: dict) -> dict:
    """A task's parameters with its methods spelled so that a worker process resolves them (plugins.portable): a
    name registered in this process travels as its module:callable, or the sweep is refused before it starts."""
    from hvs_sim.plugins import portable

    out = dict(params)
    for key in ("tracker", "controller", "policy"):
        if out.get(key) is not None:
            out[key] = portable(key, out[key])
    return out


def _write_atomic(path: Path, data: dict) -> None:
    from hvs_sim.outputs import write_atomic

    write_atomic(path, json.dumps(data, indent=1), recorded=None)  # the sweep's own folder: spec.json marks it


def _run_local(jobs, workers, on_done, progress) -> None:
    from hvs_sim.bench.pool import run_jobs

    for record in run_jobs(run_task, jobs, workers, "sweep (local)", "task", progress):
        on_done(record)


def _run_ray(jobs, workers, address, on_done, progress) -> None:
    try:
        import ray
    except ImportError:
        raise ConfigError("--engine ray needs Ray: pip install 'hvs_sim[ray]' (or pip install ray)") from None
    from tqdm.auto import tqdm

    env = {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "OMP_NUM_THREADS": "1"}
    if address:
        ray.init(address=address, runtime_env={"env_vars": env}, log_to_driver=False)
    else:  # a local instance with `workers` CPUs
        ray.init(num_cpus=workers, include_dashboard=False, runtime_env={"env_vars": env}, log_to_driver=False)
    remote = ray.remote(num_cpus=1, max_retries=0)(run_task)
    pending = {remote.remote(job): job for job in jobs}
    bar = tqdm(total=len(jobs), desc="sweep (ray)", unit="task", disable=not progress)
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                job = pending.pop(ref)
                try:
                    record = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a lost worker or node: record it, go on
                    record = {"id": job[1], "kind": job[0], "params": job[2], "status": "error",
                              "error": f"{type(exc).__name__}: {exc}"}
                on_done(record)
                bar.update(1)
    finally:
        for ref in pending:  # interrupted: stop what is in flight
            ray.cancel(ref, force=True)
        bar.close()
        ray.shutdown()


SWEEP_FILES = ("results.csv", "report.md", "report.png")  # what a sweep writes beside spec.json and tasks/


def _check_sweep_folder(out: Path) -> Path:
    """A sweep writes into a new or empty folder or one of its own (spec.json): never over a results.csv (or a
    report) in a folder that is not a sweep's, and `tasks` must be a folder."""
    tasks = out / "tasks"
    if tasks.is_symlink() or (tasks.exists() and not tasks.is_dir()):
        raise ConfigError(f"{tasks} is a file or a link, where a sweep keeps its task records in a folder; give "
                          "another --out")
    if not (out / "spec.json").is_file():
        clash = [n for n in SWEEP_FILES if (out / n).exists() or (out / n).is_symlink()]
        if clash:
            raise ConfigError(f"{out} is not a sweep folder (no spec.json) and holds {', '.join(clash)}, which the "
                              "sweep would replace; give a new or empty --out (nothing was written)")
    for name in ("spec.json", *SWEEP_FILES):
        if (out / name).is_symlink():
            raise ConfigError(f"{out / name} is a symbolic link; hvs_sim does not write through links: remove it or "
                              "give another --out")
    return out


def _lock(out: Path):
    """The sweep folder's lock, held until the returned file is closed (or the process ends, even killed): a second
    sweep into the folder is refused instead of racing on its files."""
    import fcntl

    from hvs_sim.outputs import output_error

    try:
        f = open(out / LOCK_NAME, "a+")  # noqa: SIM115 - closed by the caller
    except OSError as exc:  # a read-only or full disk
        raise output_error(out / LOCK_NAME, exc) from None
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.seek(0)
        holder = f.read().strip() or "another process"
        f.close()
        raise ConfigError(f"another sweep is writing {out} ({holder}); wait for it to end, or give another --out") \
            from None
    try:
        f.seek(0)
        f.truncate()
        f.write(f"pid {os.getpid()}")
        f.flush()
    except OSError as exc:  # the holder's pid did not fit on the disk: the lock itself is held, the sweep cannot go on
        f.close()
        raise output_error(out / LOCK_NAME, exc) from None
    return f


def _check_spec_file(spec: SweepSpec, out: Path) -> None:
    """A folder holds one spec's tasks: a different spec into it is refused (its results would be mixed)."""
    path = out / "spec.json"
    if not path.exists():
        return
    try:
        old = SweepSpec(**json.loads(path.read_text()))
    except (OSError, ValueError, TypeError):
        return  # an unreadable spec.json (cut by a full disk) is replaced by this one
    if spec_hash(old) != spec_hash(spec):
        raise ConfigError(f"{out} holds another sweep's tasks (spec.json differs from this spec); give another --out, "
                          "or remove that folder to start over")


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


def run_sweep(spec: SweepSpec, out, engine: str = "local", workers: int = 1, address: str | None = None,
              progress: bool = True, retry_failed: bool = True, max_tasks: int = MAX_TASKS) -> dict:
    """Run every task of `spec` not yet done in `out`; returns counts. Writes tasks/*.json as tasks
    finish and results.csv at the end (also when interrupted: the tasks done so far). Failed tasks are run
    again unless `retry_failed` is off; an unreadable task record is moved to tasks/corrupt/ and its task re-run."""
    from hvs_sim.outputs import prepare_out_dir, write_atomic

    if engine not in ENGINES:
        raise choice_error("engine", engine, ENGINES)
    check_number("workers", workers, 1, integer=True)
    check_number("max_tasks", max_tasks, 1, integer=True)
    if address and engine != "ray":
        raise ConfigError("--address joins a Ray cluster: it needs --engine ray")
    n = grid_size(spec)
    if n > max_tasks:
        raise ConfigError(f"the spec's grid has {n} tasks, more than {max_tasks}; shorten its axes, or raise the limit "
                          "(--max-tasks)")
    check_grid(spec)
    out = _check_sweep_folder(prepare_out_dir(out))
    lock = _lock(out)
    try:
        _check_spec_file(spec, out)
        tasks_dir = out / "tasks"
        tasks_dir.mkdir(exist_ok=True)
        write_atomic(out / "spec.json", json.dumps(dataclasses.asdict(spec), indent=2))
        remote = engine == "ray" or workers > 1
        jobs = [(spec.kind, task_id(spec.kind, p), p, _portable(p) if remote else p) for p in spec.tasks()]
        state = {j[1]: _task_state(tasks_dir / f"{j[1]}.json") for j in jobs}
        for tid, s in state.items():
            if s == "corrupt":
                (tasks_dir / "corrupt").mkdir(exist_ok=True)
                os.replace(tasks_dir / f"{tid}.json", tasks_dir / "corrupt" / f"{tid}.{int(time.time())}.json")
        rerun = {"missing", "corrupt"} | ({"error"} if retry_failed else set())
        pending = [j for j in jobs if state[j[1]] in rerun]
        counts = {"tasks": len(jobs), "skipped_done": len(jobs) - len(pending), "ran": 0, "errors": 0,
                  "retried_failed": sum(state[j[1]] == "error" for j in pending),
                  "corrupt_rerun": sum(state[j[1]] == "corrupt" for j in pending)}

        def on_done(record: dict) -> None:
            record["engine"] = engine
            _write_atomic(tasks_dir / f"{record['id']}.json", record)
            counts["ran"] += 1
            counts["errors"] += record["status"] != "ok"

        try:
            if pending:
                if engine == "ray":
                    _run_ray(pending, workers, address, on_done, progress)
                else:
                    _run_local(pending, workers, on_done, progress)
        finally:
            write_table(spec, out)
    finally:
        lock.close()
    return counts


# ------------------------------------------------------------------------------------ results


def load_records(spec: SweepSpec, out, unreadable: list | None = None) -> list[dict]:
    """The finished tasks of `spec` in `out` (grid order); the ids of damaged records are appended to `unreadable`."""
    tasks_dir = Path(out) / "tasks"
    records = []
    for p in spec.tasks():
        f = tasks_dir / f"{task_id(spec.kind, p)}.json"
        state = _task_state(f)
        if state in ("ok", "error"):  # an unreadable record counts as not done (re-run sets it aside)
            records.append(json.loads(f.read_text()))
        elif state == "corrupt" and unreadable is not None:
            unreadable.append(f.stem)
    return records


def _flat_metrics(record: dict) -> dict:
    return {k: v for k, v in record.get("metrics", {}).items() if k != "errors"}


def write_table(spec: SweepSpec, out) -> Path:
    """results.csv: one row per finished task, its parameters then its metrics."""
    records = load_records(spec, out)
    params = list(dict.fromkeys(k for p in spec.tasks() for k in p))
    metrics = list(dict.fromkeys(k for r in records for k in _flat_metrics(r)))
    import io

    from hvs_sim.outputs import write_atomic

    path = Path(out) / "results.csv"
    with io.StringIO(newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "status", *params, *metrics, "task_seconds", "engine", "error"])
        for r in records:
            m = _flat_metrics(r)
            w.writerow([r["id"], r["status"], *(r["params"].get(k, "") for k in params),
                        *("" if m.get(k) is None else m[k] for k in metrics), r.get("task_seconds", ""),
                        r.get("engine", ""), r.get("error", "")])
        write_atomic(path, f.getvalue())
    return path


def report(out, by: list[str], figures: bool = True) -> str:
    """Summary grouped by parameters (`by`), as markdown (also written to report.md), and figures."""
    out = Path(out)
    spec_file = out / "spec.json"
    if not spec_file.exists():
        raise ConfigError(f"{out} holds no sweep (spec.json missing); run `hvs-sim sweep SPEC --out {out}` first")
    try:
        spec = SweepSpec(**json.loads(spec_file.read_text()))
    except (OSError, ValueError, TypeError) as exc:
        raise ConfigError(f"{spec_file} cannot be read ({type(exc).__name__}: {exc}); run the sweep's spec into {out} "
                          "again to rewrite it") from None
    unreadable: list[str] = []
    records = load_records(spec, out, unreadable)
    damaged = (f"{len(unreadable)} task record(s) unreadable or damaged, left out (re-run the sweep to run them "
               f"again): {', '.join(unreadable[:5])}" + (", …" if len(unreadable) > 5 else "")) if unreadable else ""
    if not records:
        raise ConfigError(f"{out}: no finished tasks yet" + (f"; {damaged}" if damaged else ""))
    keys = list(spec.tasks()[0])
    bad = [b for b in by if b not in keys]
    if bad or not by:
        raise ConfigError(f"--by {','.join(by) or '(nothing)'}: group by task parameters; accepted: {', '.join(keys)}")
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault(tuple(r["params"][b] for b in by), []).append(r)
    if spec.kind == "servo":
        head = ["tasks", "errors", "success", "median convergence (s)", "median final error (px)"]
    else:
        head = ["tasks", "errors", "≤ 2 px (pooled frames)", "median px", "p95 px"]
    lines = [f"| {' | '.join(by)} | {' | '.join(head)} |", "|" + "---|" * (len(by) + len(head))]
    stats = {}
    for g, rs in groups.items():
        ok = [r["metrics"] for r in rs if r["status"] == "ok"]
        if spec.kind == "servo":
            conv = [m["seconds_to_converge"] for m in ok if m["seconds_to_converge"] is not None]
            cells = [len(rs), len(rs) - len(ok), f"{100 * np.mean([m['success'] for m in ok]):.0f} %" if ok else "–",
                     f"{np.median(conv):.2f}" if conv else "–",
                     f"{np.median([m['final_error_px'] for m in ok]):.2f}" if ok else "–"]
            stats[g] = {"success": float(np.mean([m["success"] for m in ok])) if ok else 0.0, "convergence": conv,
                        "final": [m["final_error_px"] for m in ok]}
        else:
            err = np.concatenate([m["errors"] for m in ok]) if ok else np.zeros(0)
            cells = [len(rs), len(rs) - len(ok), f"{100 * np.mean(err <= 2):.1f} %" if err.size else "–",
                     f"{np.median(err):.2f}" if err.size else "–", f"{np.percentile(err, 95):.2f}" if err.size else "–"]
            stats[g] = {"errors": err}
        lines.append(f"| {' | '.join(map(str, g))} | {' | '.join(map(str, cells))} |")
    text = "\n".join(lines) + "\n" + (f"\n{damaged}\n" if damaged else "")
    from hvs_sim.outputs import write_atomic

    write_atomic(out / "report.md", text)
    if figures:
        _report_figures(spec.kind, stats, by, out)
    return text


def _cdf(ax, labels: list[str], samples: list, threshold: float, threshold_label: str, xlabel: str, ylabel: str) -> None:
    """One CDF per group on a log axis, with the threshold line."""
    for label, values in zip(labels, samples):
        xs = np.sort(values)
        ax.plot(np.maximum(xs, 1e-3), np.arange(1, len(xs) + 1) / max(len(xs), 1), label=label)
    ax.set_xscale("log")
    ax.axvline(threshold, ls="--", color="k", lw=0.8, label=threshold_label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)


def _report_figures(kind: str, stats: dict, by: list[str], out: Path) -> None:
    from hvs_sim.viz.figures import plt

    labels = [" / ".join(map(str, g)) for g in stats]
    if kind == "servo":
        fig, ax = plt.subplots(1, 3, figsize=(16, 4.2))
        ax[0].barh(labels, [100 * s["success"] for s in stats.values()], color="tab:green")
        ax[0].set_xlabel("success (%)")
        ax[0].set_xlim(0, 100)
        ax[1].boxplot([s["convergence"] or [np.nan] for s in stats.values()], vert=False, tick_labels=labels)
        ax[1].set_xlabel("time to converge (s)")
        _cdf(ax[2], labels, [s["final"] for s in stats.values()], SUCCESS_PX, f"success ≤ {SUCCESS_PX:g} px",
             "final error (px)", "fraction of episodes")
    else:
        fig, ax = plt.subplots(1, 2, figsize=(13, 4.2))
        ax[0].barh(labels, [100 * np.mean(s["errors"] <= 2) if s["errors"].size else 0 for s in stats.values()],
                   color="tab:blue")
        ax[0].set_xlabel("frames ≤ 2 px (%)")
        ax[0].set_xlim(0, 100)
        _cdf(ax[1], labels, [s["errors"] for s in stats.values()], 2.0, "2 px", "tracking error (px)",
             "fraction of frames")
    fig.suptitle(f"sweep grouped by {', '.join(by)}")
    fig.tight_layout()
    from hvs_sim.outputs import save_figure

    save_figure(fig, out / "report.png", dpi=90)
    plt.close(fig)
