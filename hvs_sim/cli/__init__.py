"""The `hvs-sim` command.

One module per command or close group of commands (scene.py, run.py, bench.py, sweep.py, misc.py), what they
share in common.py; here `main`, the parser that gathers the commands, and the names other code imports from
`hvs_sim.cli` (every name the single module cli.py had)."""

from __future__ import annotations

import argparse
import sys

from hvs_sim import outputs
from hvs_sim.cli.bench import (
    BENCH_OUTPUTS,
    SMOKE_NOTE,
    _apply_suite,
    _check_bench_options,
    _cmd_bench_sim,
    add_bench_parser,
    cmd_bench,
    cmd_bench_compare,
    cmd_bench_natural,
)
from hvs_sim.cli.common import (
    _SIGTERM_SEEN,
    EXIT_OUTPUT_FAILED,
    EXIT_SIGINT,
    EXIT_SIGTERM,
    HelpFormatter,
    Terminated,
    _add_scene_args,
    _given,
    _on_sigterm,
    _provenance,
    _scenario_from_args,
    _target_overrides,
    stop_reason,
)
from hvs_sim.cli.misc import (
    add_budget_parser,
    add_dataset_parser,
    add_demo_parser,
    add_train_parser,
    cmd_budget,
    cmd_dataset,
    cmd_demo,
    cmd_train,
)
from hvs_sim.cli.results import add_results_parser
from hvs_sim.cli.run import _check_viewer, add_run_parser, cmd_run, parse_start_offset
from hvs_sim.cli.scene import SCENE_OUTPUTS, add_scene_parser, add_scenes_parser, cmd_scene, cmd_scenes
from hvs_sim.cli.sweep import add_sweep_parser, cmd_sweep
from hvs_sim.errors import HvsError

__all__ = [
    "BENCH_OUTPUTS", "EXIT_OUTPUT_FAILED", "EXIT_SIGINT", "EXIT_SIGTERM", "SCENE_OUTPUTS", "SMOKE_NOTE",
    "_SIGTERM_SEEN", "HelpFormatter", "Terminated", "_add_scene_args", "_apply_suite", "_check_bench_options",
    "_check_viewer", "_cmd_bench_sim", "_given", "_on_sigterm", "_provenance", "_scenario_from_args",
    "_target_overrides", "build_parser", "cmd_bench", "cmd_bench_compare", "cmd_bench_natural", "cmd_budget",
    "cmd_dataset", "cmd_demo", "cmd_run", "cmd_scene", "cmd_scenes", "cmd_sweep", "cmd_train", "main", "parse_start_offset"
]


def build_parser() -> argparse.ArgumentParser:
    from hvs_sim import __version__

    parser = argparse.ArgumentParser(prog="hvs-sim", description="Occlusion-robust visual servoing simulator",
                                     formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"hvs-sim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    add_scene_parser(sub)
    add_run_parser(sub)
    add_train_parser(sub)
    add_bench_parser(sub)
    add_sweep_parser(sub)
    add_budget_parser(sub)
    add_dataset_parser(sub)
    add_scenes_parser(sub)
    add_demo_parser(sub)
    add_results_parser(sub)

    from hvs_sim.cli.track import add_track_parser  # here, not at the top: it loads OpenCV and the trackers
    add_track_parser(sub)
    _no_abbreviations(parser)
    return parser


def _no_abbreviations(parser: argparse.ArgumentParser) -> None:
    """An option must be written in full (`run --roi 5` is not `--roi-inset 5`), in every command's parser."""
    parser.allow_abbrev = False
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in dict.fromkeys(action.choices.values()):
                _no_abbreviations(child)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # argparse has printed the usage error (or --help); a caller gets the code back
        return exc.code if isinstance(exc.code, int) else 2
    args.argv = argv
    if getattr(args, "command", None) == "bench" and args.out is None:
        args.out = f"out/bench_{args.what}"
    if getattr(args, "workers", 1) < 1:
        print("hvs-sim: error: --workers must be >= 1", file=sys.stderr)
        return 2
    import signal
    import threading

    handle = threading.current_thread() is threading.main_thread()  # signal handlers live in the main thread
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if handle else None
    _SIGTERM_SEEN.clear()
    outputs.begin_command()
    try:
        code = args.func(args)
    except HvsError as exc:  # an OutputError (a full disk) too: the partial temporaries go, complete outputs stay
        outputs.discard_pending()
        print(f"hvs-sim: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        if not outputs.is_output_failure(exc):
            raise
        outputs.discard_pending()  # a writer the layer does not wrap: still no traceback and no partial file
        print(f"hvs-sim: error: {outputs.shown_name(exc.filename) or 'a file'}: {exc.strerror or exc}; "
              f"{outputs.complete_note()}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # user code (a plugin) called sys.exit: not a result, say so
        outputs.discard_pending()
        print(f"hvs-sim: error: user code called sys.exit({exc.code!r}) while `hvs-sim {args.command}` ran; it "
              "was stopped there (a plugin must return or raise, not exit)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"hvs-sim: {stop_reason()}: stopped; what was "
              "finished is kept, and summaries written so far say interrupted", file=sys.stderr)
        code = EXIT_SIGINT
    finally:
        outputs.end_command()
        if handle:
            signal.signal(signal.SIGTERM, previous)
    return EXIT_SIGTERM if _SIGTERM_SEEN and code == EXIT_SIGINT else code
