"""The one way benchmarks fan jobs out over local processes."""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import signal
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

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


def run_jobs(fn: Callable, jobs: Sequence, workers: int, desc: str, unit: str, progress: bool = True) -> Iterator:
    """Yield fn(job) for every job, in order, with a progress bar.

    workers > 1: spawned processes (a process forked after torch or EGL started threads can hang).
    On Ctrl-C, SIGTERM or any error the workers are ended before the exception goes on, so none is
    left behind."""
    from tqdm.auto import tqdm

    bar = tqdm(total=len(jobs), disable=not progress, desc=desc, unit=unit)
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


def collect_jobs(fn: Callable, jobs: Sequence, config, out: Path, desc: str, unit: str, progress: bool = True) -> list:
    """Every job's result (run_jobs with config.workers), in order. Interrupted part-way, it writes
    out/summary.json marked interrupted with the keys (each result's first item) that finished,
    then lets the interrupt go on."""
    done = []
    try:
        done.extend(run_jobs(fn, jobs, config.workers, desc, unit, progress))  # keeps what came before an interrupt
    except KeyboardInterrupt:
        write_atomic(Path(out, "summary.json"), json.dumps({
            "interrupted": True, "completed_jobs": len(done), "total_jobs": len(jobs),
            "completed": [list(r[0]) if isinstance(r[0], tuple) else r[0] for r in done],
            "config": config_json(config)}, indent=2))
        raise
    return done


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
