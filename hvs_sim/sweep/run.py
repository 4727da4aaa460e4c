"""Running a sweep: the folder it writes (its own, locked against a second sweep, holding one spec's tasks), which
tasks are still to run, and the engine that runs them (the local pool or Ray)."""

from __future__ import annotations

import dataclasses
import json
import os
import time
from pathlib import Path

from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.sweep.report import write_table
from hvs_sim.sweep.spec import SweepSpec, grid_size, spec_hash, task_id
from hvs_sim.sweep.tasks import _task_state, check_grid, run_task
from hvs_sim.validate import check_number

ENGINES = ("local", "ray")
MAX_TASKS = 10_000  # a grid larger than this is refused before anything is built (run_sweep's max_tasks overrides)
LOCK_NAME = ".sweep.lock"  # held by the one sweep that writes a folder (fcntl.flock; released when the process ends)
SWEEP_FILES = ("results.csv", "report.md", "report.png")  # what a sweep writes beside spec.json and tasks/


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
