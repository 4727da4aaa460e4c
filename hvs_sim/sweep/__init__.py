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

The parts: spec.py (the TOML spec, what it may name, the grid and task ids), tasks.py (one task run, and its record
read back), run.py (run_sweep: the folder, its lock, the local pool or Ray), report.py (results.csv, report.md and
its figure). The names below are the sweep's API.
"""

from hvs_sim.sweep.report import load_records, report, write_table
from hvs_sim.sweep.run import ENGINES, LOCK_NAME, MAX_TASKS, SWEEP_FILES, run_sweep
from hvs_sim.sweep.spec import (
    DEFAULTS,
    KINDS,
    TIMING_METRICS,
    SweepSpec,
    accepted_keys,
    grid_size,
    load_spec,
    parse_spec,
    spec_hash,
    task_id,
)
from hvs_sim.sweep.tasks import check_grid, run_task

__all__ = ["DEFAULTS", "ENGINES", "KINDS", "LOCK_NAME", "MAX_TASKS", "SWEEP_FILES", "TIMING_METRICS", "SweepSpec",
           "accepted_keys", "check_grid", "grid_size", "load_records", "load_spec", "parse_spec", "report",
           "run_sweep", "run_task", "spec_hash", "task_id", "write_table"]
