"""`hvs-sim sweep`: run a sweep from a TOML spec, or report on one (the work itself is the hvs_sim.sweep package)."""

from __future__ import annotations

from hvs_sim.cli.common import HelpFormatter
from hvs_sim.errors import ConfigError


def cmd_sweep(args) -> int:
    """`hvs-sim sweep SPEC.toml --out DIR` runs a sweep; `hvs-sim sweep report DIR --by a,b` summarises one."""
    from hvs_sim import sweep

    if args.target[0] == "report":
        if len(args.target) != 2:
            raise ConfigError("usage: hvs-sim sweep report DIR --by KEY[,KEY...]")
        by = [b.strip() for b in (args.by or "").split(",") if b.strip()]
        print(sweep.report(args.target[1], by), end="")
        print(f"report: {args.target[1]}/report.md, {args.target[1]}/report.png")
        return 0
    if len(args.target) != 1:
        raise ConfigError("usage: hvs-sim sweep SPEC.toml --out DIR [--engine local|ray] [--address ADDR] [--workers N]")
    if args.by:
        raise ConfigError("--by applies to `hvs-sim sweep report DIR`")
    spec = sweep.load_spec(args.target[0])
    if args.out is None:
        raise ConfigError("give --out DIR: where the sweep keeps its tasks and results (re-running resumes there)")
    counts = sweep.run_sweep(spec, args.out, engine=args.engine, workers=args.workers, address=args.address,
                             retry_failed=not args.no_retry_failed, max_tasks=args.max_tasks or sweep.MAX_TASKS)
    print(f"{counts['tasks']} tasks: {counts['skipped_done']} already done, {counts['ran']} ran "
          f"({counts['retried_failed']} failed before, {counts['corrupt_rerun']} with an unreadable record set aside "
          f"in tasks/corrupt/), {counts['errors']} of those failed (recorded with their error)")
    print(f"results: {args.out}/results.csv (report: hvs-sim sweep report {args.out} --by tracker)")
    return 0


def add_sweep_parser(sub) -> None:
    p = sub.add_parser("sweep", formatter_class=HelpFormatter,
                       help="parameter sweeps from a TOML spec, on a local pool or Ray; resumable (hvs_sim/sweep/)")
    p.add_argument("target", nargs="+", metavar="SPEC.toml | report DIR",
                   help="a sweep spec to run, or `report DIR` to summarise a sweep")
    p.add_argument("--out", default=None, help="sweep folder: tasks/*.json, results.csv (re-running resumes)")
    p.add_argument("--engine", default="local", choices=("local", "ray"), help="local process pool or Ray")
    p.add_argument("--address", default=None, help="an existing Ray cluster to join (engine ray; default: start a "
                   "local instance)")
    p.add_argument("--workers", type=int, default=1, help="processes (local) or CPUs of a local Ray instance")
    p.add_argument("--by", default=None, help="report: parameters to group by, comma-separated, e.g. tracker,scenario")
    p.add_argument("--no-retry-failed", action="store_true",
                   help="on a re-run, keep the tasks that failed as they are (default: run them again)")
    p.add_argument("--max-tasks", type=int, default=None,
                   help="refuse a spec whose grid has more tasks than this, before building it (default: "
                        "hvs_sim.sweep.MAX_TASKS, 10 000)")
    p.set_defaults(func=cmd_sweep)
