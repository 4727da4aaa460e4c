"""The one way benchmarks fan jobs out over local processes."""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import json
import multiprocessing
import os
import re
import signal
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from hvs_sim.errors import ConfigError
from hvs_sim.manifest import clear_written
from hvs_sim.outputs import write_atomic

PR_SET_PDEATHSIG = 1  # linux/prctl.h
# torch threads in every episode and sequence, whatever --workers: sums split over another number of threads round
# differently in the last bits, which a closed loop can amplify into another episode; one thread keeps a seed's
# record the same however the benchmark is run (tests/test_bench.py)
EPISODE_THREADS = 1


def die_with_parent() -> None:
    """Ask Linux to kill this process when the one that started it dies, however it dies (SIGKILL included): a
    killed benchmark or sweep leaves no worker behind. Elsewhere (no prctl) the pool's own shutdown still ends them."""
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # no libc symbol: keep the pool's shutdown as the only guard
        return
    if os.getppid() == 1:  # the parent died before the request took effect
        os._exit(1)


def _ignore_sigint() -> None:
    """Workers leave Ctrl-C to the parent, which ends them (otherwise each prints its own traceback), and die with it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent()


def run_jobs(fn: Callable, jobs: Sequence, workers: int, desc: str, unit: str, progress: bool = True,
             initial: int = 0, total: int | None = None) -> Iterator:
    """Yield fn(job) for every job, in order, with a progress bar.

    workers > 1: spawned processes (a process forked after torch or EGL started threads can hang).
    On Ctrl-C, SIGTERM or any error the workers are ended before the exception goes on, so none is
    left behind. initial/total: the bar of a resumed run counts the jobs done before (its ETA is the pace of these)."""
    from tqdm.auto import tqdm

    bar = tqdm(total=len(jobs) + initial if total is None else total, initial=initial, disable=not progress,
               desc=desc, unit=unit)
    try:
        if workers <= 1:
            for job in jobs:
                yield fn(job)
                bar.update(1)
            return
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"), initializer=_ignore_sigint)
        try:
            for out in pool.map(fn, jobs):
                yield out
                bar.update(1)
        except BaseException:
            procs = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                p.terminate()
            for p in procs:
                p.join(5)
            raise
        pool.shutdown()
    finally:
        bar.close()


def episode_threads() -> None:
    """Fix the numerics of the episode or sequence about to run in this process (EPISODE_THREADS)."""
    import torch

    torch.set_num_threads(EPISODE_THREADS)


def config_json(config) -> dict:
    """A frozen benchmark config as JSON-ready fields (tuples as lists; a camera model given as a SensorModel, from
    Python, as its fields)."""
    def ready(v):
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return {k: ready(x) for k, x in dataclasses.asdict(v).items()}
        return list(v) if isinstance(v, tuple) else v

    return {k: ready(v) for k, v in config.__dict__.items()}


RECORDS_DIR = "episodes"  # one atomic JSON record per finished episode or sequence, beside summary.json
RUN_RECORD = "run.json"  # in RECORDS_DIR: the config the records were made with (checked by --resume)
RESUME_IGNORES = ("workers",)  # config fields that do not change a record (EPISODE_THREADS)
_NAME_CHARS = re.compile(r"[^A-Za-z0-9._-]+")
KEY_HASH_CHARS = 8  # a method name such as {pkg.mod:make}/{pkg.law:make} loses characters to the file name


def record_name(key) -> str:
    """The file name of a job's record: its key readable, plus a short hash of the full key (distinct keys may read
    alike once their odd characters are replaced)."""
    parts = [str(k) for k in (key if isinstance(key, (tuple, list)) else (key,))]
    digest = hashlib.sha1(json.dumps(parts).encode()).hexdigest()[:KEY_HASH_CHARS]
    return f"{_NAME_CHARS.sub('_', '__'.join(parts))[:120]}-{digest}.json"


def to_record(value):
    """A job's result as JSON (arrays with their dtype, images as base64 bytes): reading it back with from_record
    gives the same numbers bit for bit, so a resumed run computes what an uninterrupted one does."""
    if isinstance(value, np.ndarray):
        if value.dtype == np.uint8:
            return {"__ndarray_b64__": base64.b64encode(np.ascontiguousarray(value).tobytes()).decode(),
                    "shape": list(value.shape)}
        return {"__ndarray__": value.tolist(), "dtype": value.dtype.str}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {str(k): to_record(v) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        return [to_record(v) for v in value]
    return value


def from_record(value):
    """The inverse of to_record (tuples come back as lists; a job's key is made a tuple by the caller)."""
    if isinstance(value, dict):
        if "__ndarray_b64__" in value:
            raw = base64.b64decode(value["__ndarray_b64__"])
            return np.frombuffer(raw, np.uint8).reshape(value["shape"]).copy()
        if "__ndarray__" in value:
            return np.array(value["__ndarray__"], dtype=np.dtype(value["dtype"]))
        return {k: from_record(v) for k, v in value.items()}
    if isinstance(value, list):
        return [from_record(v) for v in value]
    return value


def _job_key(job) -> tuple:
    """What names a job: its first three fields (scenario, method or mount, seed; source, kind, seed)."""
    return tuple(job[:3])


def _check_resumable(records: Path, recorded_config: dict, kind: str) -> None:
    """Refuse to complete a folder whose records were made with other settings, naming the first that differs."""
    path = records / RUN_RECORD
    if not path.is_file():
        raise ConfigError(f"--resume: {records.parent} holds no {RECORDS_DIR}/{RUN_RECORD}, so no record of an "
                          "earlier run to complete; run without --resume (and with --overwrite to replace it)")
    try:
        run = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"--resume: {path} cannot be read ({exc})") from None
    if run.get("kind") != kind:
        raise ConfigError(f"--resume: {records.parent} holds a `{run.get('kind')}` run, not `{kind}`")
    old = run.get("config", {})
    for field in sorted(set(old) | set(recorded_config)):
        if field in RESUME_IGNORES:
            continue
        if old.get(field) != recorded_config.get(field):
            raise ConfigError(f"--resume: {records.parent} was run with {field} = {old.get(field)!r}, this command "
                              f"gives {recorded_config.get(field)!r}; give the interrupted run's options (its "
                              f"{RECORDS_DIR}/{RUN_RECORD}) to complete it, or run afresh with --overwrite")


def _load_record(path: Path, key: tuple):
    """A finished job's result from its record, or None when it is missing or not this job's (then it runs again)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None  # a record is written atomically, so this is a stray file: run the job again
    if [str(k) for k in data.get("key", [])] != [str(k) for k in key]:
        return None
    result = from_record(data["result"])
    return (tuple(data["key"]), *result[1:])


def collect_jobs(fn: Callable, jobs: Sequence, config, out: Path, desc: str, unit: str, progress: bool = True,
                 resume: bool = False, ran: list | None = None) -> list:
    """Every job's result (run_jobs with config.workers), in order, each recorded as it ends in out/episodes/
    (atomic JSON; what is returned is the record read back, so a resumed run computes exactly what an uninterrupted
    one does). resume: the jobs recorded already are read, not run (the config must match the recorded one).
    Interrupted part-way, it writes out/summary.json marked interrupted, with the finished jobs' records, then lets
    the interrupt go on. ran: filled with the keys of the jobs run now (not read from records), for throughput."""
    out = Path(out)
    records = out / RECORDS_DIR
    recorded_config = config_json(config)
    kind = desc.removeprefix("bench ")
    results: dict[int, tuple] = {}
    if resume:
        _check_resumable(records, recorded_config, kind)
        for i, job in enumerate(jobs):
            found = _load_record(records / record_name(_job_key(job)), _job_key(job))
            if found is not None:
                results[i] = found
    else:
        if records.is_dir():  # an earlier run's records (the folder was given with --overwrite): not this run's,
            clear_written(records)  # and a later --resume must not read them (only files hvs_sim wrote go)
        records.mkdir(parents=True, exist_ok=True)
        write_atomic(records / RUN_RECORD, json.dumps({"kind": kind, "config": recorded_config}, indent=2))
    todo = [i for i in range(len(jobs)) if i not in results]
    if progress:
        print(f"{desc}: {len(todo)} {unit}(s) to run" + (f", {len(results)} recorded already" if results else "")
              + f", {config.workers} worker(s); an estimate of the time follows the first", file=sys.stderr)
    started = time.perf_counter()
    try:
        for n, (i, res) in enumerate(zip(todo, run_jobs(fn, [jobs[i] for i in todo], config.workers, desc, unit,
                                                        progress, initial=len(results), total=len(jobs)))):
            record = {"key": [to_record(k) for k in _job_key(jobs[i])], "result": to_record(res)}
            text = json.dumps(record, indent=1)
            write_atomic(records / record_name(_job_key(jobs[i])), text)
            results[i] = _load_record_text(text)
            if ran is not None:
                ran.append(results[i][0])
            if n == 0 and progress and len(todo) > 1:
                first = time.perf_counter() - started
                left = first * (len(todo) - 1) / max(1, min(config.workers, len(todo) - 1))
                _say(f"{desc}: the first {unit} took {first:.0f} s; the other {len(todo) - 1} should take about "
                     f"{_duration(left)} with {config.workers} worker(s) (the bar's ETA follows the pace)")
    except KeyboardInterrupt:
        done = [results[i] for i in sorted(results)]
        write_atomic(out / "summary.json", json.dumps({
            "interrupted": True, "completed_jobs": len(done), "total_jobs": len(jobs),
            "completed": [list(r[0]) for r in done],
            "resume": f"complete it with the same command and --resume --out {out}",
            "config": recorded_config,
            "records": [{"key": list(r[0]), "result": _without_images(to_record(r[1:]))} for r in done]}, indent=1))
        print(f"{desc}: {len(done)} of {len(jobs)} {unit}(s) are recorded in {records}/; the same command with "
              f"--resume runs the other {len(jobs) - len(done)}", file=sys.stderr)
        raise
    return [results[i] for i in range(len(jobs))]


def _without_images(value):
    """A record for the partial summary: images (previews) only named by their shape; they stay in episodes/."""
    if isinstance(value, dict):
        if "__ndarray_b64__" in value:
            return {"image_shape": value["shape"], "in": RECORDS_DIR}
        return {k: _without_images(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_without_images(v) for v in value]
    return value


def _load_record_text(text: str) -> tuple:
    data = json.loads(text)
    return (tuple(data["key"]), *from_record(data["result"])[1:])


def _say(text: str) -> None:
    from tqdm.auto import tqdm

    tqdm.write(text, file=sys.stderr)


SECONDS_PER_MINUTE = 60


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 2 * SECONDS_PER_MINUTE else f"{seconds / SECONDS_PER_MINUTE:.0f} min"


def write_frames_csv(results: dict, path: Path, key_columns: tuple[str, str, str]) -> None:
    """frames.csv of a tracking benchmark: one row per (sequence key, method, frame)."""
    import csv

    from hvs_sim.outputs import open_output, settle, temporary_beside

    tmp = temporary_beside(path)
    with open_output(tmp) as f:
        w = csv.writer(f)
        w.writerow([*key_columns, "method", "frame", "error_px", "occlusion", "mode", "ms", "op_estimate"])
        for key, per in results.items():
            for m, r in per.items():
                for i in range(len(r["error"])):
                    w.writerow([*key, m, i, f"{r['error'][i]:.4f}", f"{r['occlusion'][i]:.4f}", r["mode"][i],
                                f"{r['ms'][i]:.2f}", f"{r['occ_est'][i]:.3f}"])
    settle(tmp, path, keep=True)
