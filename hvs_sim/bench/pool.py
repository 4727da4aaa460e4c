"""The one way benchmarks fan jobs out over local processes."""

from __future__ import annotations

import json
import multiprocessing
import signal
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def _ignore_sigint() -> None:
    """Workers leave Ctrl-C to the parent, which ends them; otherwise each prints its own traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


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


def write_interrupted(out: Path, done: list, total: int, config: dict) -> None:
    """summary.json of a benchmark stopped part-way: which jobs finished, marked interrupted."""
    Path(out, "summary.json").write_text(json.dumps({
        "interrupted": True, "completed_jobs": len(done), "total_jobs": total,
        "completed": [list(k) if isinstance(k, tuple) else k for k in done], "config": config}, indent=2))
