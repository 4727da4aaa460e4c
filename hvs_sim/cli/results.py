"""`hvs-sim results`: the headline results made by one command each (make), listed (list), and the published tables
generated from their data (tables) and checked against it (check)."""

from __future__ import annotations

from hvs_sim.cli.common import HelpFormatter


def cmd_results(args) -> int:
    from hvs_sim.bench import manifest

    if args.action == "list":
        for e in manifest.load_manifest().values():
            print(f"{e.name} ({e.split}): {e.folder}\n    {e.command}\n    supports: {e.supports}")
        return 0
    if args.action == "make":
        manifest.make(args.names, allow_dirty=args.allow_dirty)
        return 0
    from hvs_sim.bench import headlines

    if args.names:
        from hvs_sim.errors import ConfigError

        raise ConfigError(f"`results {args.action}` takes no names (got {' '.join(args.names)}); `results make` does")
    if args.action == "tables":
        for path in headlines.write_tables():
            print(f"wrote {path}")
        return 0
    report = headlines.check()
    print(report.text(), end="")
    return 0 if report.ok else 1


def add_results_parser(sub) -> None:
    p = sub.add_parser("results", formatter_class=HelpFormatter,
                       help="the headline results: make them from a clean tree, list them, write and check the "
                            "published tables against their data")
    p.add_argument("action", choices=("make", "list", "tables", "check"),
                   help="make [NAME…]: run the manifest's commands (experiments/results/MANIFEST.toml; all when none "
                        "is named) from a clean checkout, recording the commit at start and end in each folder's "
                        "MADE.json; list: the manifest; tables: write README's and docs/results.md's headline tables "
                        "from the folders' records; check: re-derive those tables and every cited folder's "
                        "provenance, failing on any difference")
    p.add_argument("names", nargs="*", metavar="NAME", help="make: the manifest entries to make (default all)")
    p.add_argument("--allow-dirty", action="store_true",
                   help="make: run on a checkout with uncommitted changes (MADE.json then says moved, and check "
                        "refuses to cite it)")
    p.set_defaults(func=cmd_results)
