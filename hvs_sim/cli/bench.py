"""`hvs-sim bench`: the tracking (sim or natural imagery) and servo benchmarks, the versioned suites, and
`bench compare` of two servo results."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from hvs_sim.cli.common import HelpFormatter, _given, _provenance, add_blur_argument, camera_model, finish_provenance
from hvs_sim.cliargs import add_config_options, given_options, option_flags
from hvs_sim.errors import ConfigError
from hvs_sim.outputs import fresh_out_dir, write_atomic
from hvs_sim.validate import check_number


def _check_bench_options(args) -> None:
    """Refuse options that do not apply to the chosen benchmark, rather than ignoring them (before --out is touched)."""
    if args.blur and args.what == "track" and args.imagery == "natural":
        raise ConfigError("--blur: natural imagery is warped pictures, not renders; its blur is the sequence's own "
                          "(leave --blur out, or use --imagery sim)")
    camera_model(args.camera, args.blur)  # a camera without an exposure time has no blur to make
    if args.what == "servo":
        for flag, value in (("--imagery natural", args.imagery == "natural"), ("--sources", args.sources),
                            ("--mounts", args.mounts), ("--motion", args.motion)):
            if value:
                raise ConfigError(f"{flag} applies to `bench track` only (the servo benchmark's camera is on the arm)")
        return
    for flag, value in (("--episodes", args.episodes), ("--damping", args.damping), ("--arm", args.arm),
                        *option_flags(args, bench_loop_options()),
                        ("--extra-steps", args.extra_steps), ("--safety", args.safety)):
        if value is not None:
            raise ConfigError(f"{flag} applies to `bench servo` only")
    if args.imagery == "natural":
        for flag, value in (("--mounts", args.mounts), ("--people", args.people)):
            if value:
                raise ConfigError(f"{flag} does not apply to --imagery natural (planar photos, a drawn person): "
                                  "leave it out, or use --imagery sim")
    elif args.sources or args.motion:
        raise ConfigError(f"{'--sources' if args.sources else '--motion'} applies to --imagery natural only")


def cmd_bench_natural(args) -> int:
    from hvs_sim.bench.natural import (
        DEFAULT_SEEDS,
        NATURAL_KINDS,
        NATURAL_SOURCES,
        NaturalBenchConfig,
        run_natural_bench,
        smoke_config,
    )
    from hvs_sim.bench.track import METHODS

    if args.smoke:  # small defaults; what the user names is honoured
        cfg = smoke_config(tuple(args.methods or METHODS), camera=args.camera, workers=args.workers)
        cfg = dataclasses.replace(cfg, **_given(args, ("sources", "sources"), ("scenarios", "kinds"), ("seeds", "seeds")),
                                  motion=args.motion or cfg.motion)
        print(f"SMOKE RUN ({', '.join(cfg.sources)}; {', '.join(cfg.kinds)}; {cfg.frames} frames): checks the pipeline, "
              "NOT a result")
    else:
        cfg = NaturalBenchConfig(methods=tuple(args.methods or NaturalBenchConfig.methods),
                                 sources=tuple(args.sources or NATURAL_SOURCES), kinds=tuple(args.scenarios or NATURAL_KINDS),
                                 seeds=tuple(args.seeds or DEFAULT_SEEDS), camera=args.camera, workers=args.workers,
                                 motion=args.motion or "hand")
    summary = run_natural_bench(cfg, Path(args.out), resume=getattr(args, "resume", False))
    for m, a in summary["overall"].items():
        v = summary["visible_lt_40"][m]
        t = summary["timing"][m]
        ratio = t["ratio_to_ecc"]
        print(f"{m:18s} all: {a['pct_le_2px']:5.1f}% ≤2px median {a['median_px']:.2f}px | occlusion < 40 %: "
              f"{v.get('pct_le_2px', float('nan')):5.1f}% ≤2px | {t['median_ms']:.1f} ms median"
              + ("" if ratio is None else f" ({ratio:.2f}× ecc)"))
    for kind, per in summary["per_kind"].items():
        print(f"  {kind:8s} " + "  ".join(f"{m} {v['pct_le_2px']:.1f}% ≤2px {v['median_px']:.2f}px" for m, v in per.items()))
    if args.smoke:
        print("SMOKE RUN: the figures above check the pipeline, they are NOT a result")
    return 0


BENCH_OUTPUTS = ("summary.json", "table.md", "frames.csv", "*.png")  # what a benchmark writes in --out


def cmd_bench(args) -> int:
    if args.what == "suites":
        from hvs_sim.bench.suites import describe

        print(describe(), end="")
        return 0
    if args.what == "compare":
        if getattr(args, "resume", False):
            raise ConfigError("--resume completes an interrupted `bench servo` or `bench track` run, not a compare")
        return cmd_bench_compare(args)
    if args.paths:
        raise ConfigError(f"`bench {args.what}` takes no positional folders (got {args.paths}); `bench compare A B` does")
    if args.suite:
        _apply_suite(args)
    elif args.camera is None:
        from hvs_sim.sensor import REALISTIC_PRESET

        args.camera = REALISTIC_PRESET
    _check_bench_options(args)
    origin = _resolve_seeds(args)
    if getattr(args, "resume", False):
        if _nothing_to_resume(args):
            return 0
    else:
        fresh_out_dir(args.out, args.overwrite, BENCH_OUTPUTS)
    started = _provenance(args.argv)  # the code at the start: a run may take hours, and the tree may move meanwhile
    if args.what == "track" and args.imagery == "natural":
        status = cmd_bench_natural(args)
    else:
        status = _cmd_bench_sim(args)
    path = Path(args.out) / "summary.json"
    data = json.loads(path.read_text())
    data["provenance"] = finish_provenance(started)
    if getattr(args, "resume", False):  # completed by --resume: part of its episodes ran under an earlier command
        data["resumed"] = True
    if origin is not None:
        data.update(split=origin, seeds_fresh=origin == "fresh", seeds=list(args.seeds))
        _note_seeds(Path(args.out) / "table.md", origin, args.seeds)
    write_atomic(path, json.dumps(data, indent=2))
    print(f"results: {args.out}/ (summary.json, table.md, figures)")
    return status


def _nothing_to_resume(args) -> bool:
    """--resume: refuse a folder with no run to complete (or with --overwrite, which would replace it); True, said,
    when its run finished already (a summary.json that is not marked interrupted)."""
    from hvs_sim.bench.pool import RECORDS_DIR

    out = Path(args.out)
    if args.overwrite:
        raise ConfigError("--resume completes the run in --out and --overwrite replaces it: give one")
    if not (out / RECORDS_DIR).is_dir():
        raise ConfigError(f"--resume: {out} holds no {RECORDS_DIR}/ of an earlier `bench {args.what}` run to complete "
                          "(runs before records were kept cannot be resumed); run it without --resume")
    summary = out / "summary.json"
    try:
        data = json.loads(summary.read_text()) if summary.is_file() else {"interrupted": True}
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        data = {"interrupted": True}  # a summary cut short: the records say what is left
    if data.get("interrupted"):
        return False
    print(f"{out} holds a finished run (summary.json is complete): nothing to resume")
    return True


def _bench_kind(args) -> str:
    return "natural" if args.what == "track" and args.imagery == "natural" else args.what


def _resolve_seeds(args) -> str | None:
    """Set args.seeds from --seeds, --fresh N or --split (default test) and say which they are (bench/splits.py);
    None for a smoke run that names no seeds (its own, not a result)."""
    from hvs_sim.bench.splits import DEFAULT_COUNT, DEFAULT_SPLIT, fresh_seeds, seed_origin, split_of

    kind = _bench_kind(args)
    given = [flag for flag, v in (("--seeds", args.seeds and not args.suite), ("--fresh", args.fresh is not None),
                                  ("--split", args.split)) if v]
    if len(given) > 1:
        raise ConfigError(f"{given[0]} and {given[1]} both choose the seeds: give one")
    if args.episodes is not None:
        check_number("--episodes", args.episodes, 1, integer=True)
    if args.fresh is not None and args.episodes is not None:
        raise ConfigError(f"--fresh {args.fresh} is the number of episodes drawn: leave --episodes out")
    suite = getattr(args, "suite_obj", None)
    if args.fresh is not None:
        args.seeds = list(fresh_seeds(args.fresh))
        print(f"fresh seeds from the system's entropy: {' '.join(map(str, args.seeds))}")
        return "fresh"
    if suite is not None:
        args.seeds = list(suite.seeds(args.split or DEFAULT_SPLIT))
        return args.split or DEFAULT_SPLIT
    if args.seeds:
        return seed_origin(kind, args.seeds)
    if args.smoke and not args.split:
        return None
    n = args.episodes if args.episodes is not None and kind == "servo" else DEFAULT_COUNT[kind]
    args.seeds = list(split_of(kind).seeds(args.split or DEFAULT_SPLIT, n))
    args.episodes = None  # the seeds say it now
    return args.split or DEFAULT_SPLIT


def _note_seeds(table: Path, origin: str, seeds) -> None:
    """The seeds' origin under the table's title, so a table read alone says whether its seeds were tuned on."""
    if not table.is_file():
        return
    what = {"test": "the test split (nothing was tuned on them)", "dev": "the dev split (tuning may have used them)",
            "fresh": "drawn fresh from the system's entropy for this run", "custom": "named by hand (neither split)"}
    lines = table.read_text().split("\n")
    shown = ", ".join(map(str, seeds[:6])) + (", …" if len(seeds) > 6 else "")
    lines[1:1] = ["", f"Seeds ({len(seeds)}): {what[origin]}: {shown}."]
    write_atomic(table, "\n".join(lines))


def _apply_suite(args) -> None:
    """--suite NAME: the suite's frozen settings; the methods named run alone (beside the reference methods in a suite
    `with_reference`, or those alone when none is named), and any option that would change the suite's episodes is
    refused."""
    from hvs_sim.bench.suites import get_suite

    suite = get_suite(args.suite, args.what)
    for flag, value in (("--smoke", args.smoke), ("--scenarios", args.scenarios), ("--seeds", args.seeds),
                        ("--episodes", args.episodes), ("--camera", args.camera), ("--people", args.people),
                        ("--extra-steps", args.extra_steps), ("--mounts", args.mounts), ("--arm", args.arm),
                        ("--blur", args.blur),
                        ("--imagery natural", args.imagery == "natural")):
        if value:
            raise ConfigError(f"{flag} changes what suite {suite.name} fixes (its scenarios, seeds, camera, arm, "
                              "people and steps): leave it out, or run without --suite")
    named = list(args.methods or [])
    args.methods = list(dict.fromkeys([*suite.methods, *named] if suite.with_reference or not named else named))
    args.scenarios, args.camera = list(suite.scenarios), suite.camera
    args.suite_obj = suite
    if suite.kind == "track":
        args.mounts = list(suite.mounts)


def cmd_bench_compare(args) -> int:
    from hvs_sim.bench.compare import compare, compare_figure, compare_table

    if len(args.paths) != 2:
        raise ConfigError(f"`bench compare` takes two result folders A B, got {len(args.paths)}: hvs-sim bench compare "
                          "out/mine experiments/results/occlusion-v1")
    pair = {}
    if args.methods:
        if len(args.methods) != 2:
            raise ConfigError(f"`bench compare A B --methods MA MB` takes two methods, MA of A and MB of B; got "
                              f"{len(args.methods)}")
        pair = {"methods_a": args.methods[:1], "methods_b": args.methods[1:]}
    result = compare(*args.paths, **pair)  # checked and computed before --out is cleared
    out = fresh_out_dir(args.out, args.overwrite, ("compare.json", "compare.md", "compare.png"), inputs=args.paths)
    table = compare_table(result)
    write_atomic(out / "compare.json", json.dumps(result, indent=2))
    write_atomic(out / "compare.md", table)
    compare_figure(result, out / "compare.png")
    print(table, end="")
    print(f"results: {out}/ (compare.json, compare.md, compare.png)")
    return 0


SMOKE_NOTE = "SMOKE RUN: checks that the pipeline runs end to end; the figures it prints are NOT a result"


def _cmd_bench_sim(args) -> int:
    args.people = args.people or "textured"
    if args.what == "track":
        from hvs_sim.bench.track import METHODS, TrackBenchConfig, run_track_bench

        given = _given(args, ("methods", "methods"), ("scenarios", "scenarios"), ("mounts", "mounts"), ("seeds", "seeds"))
        if args.smoke:  # small defaults; what the user names is honoured
            print(SMOKE_NOTE)
            given = {"methods": METHODS, "scenarios": ("walk_by",), "mounts": ("handheld",), "seeds": (100,), **given}
        cfg = TrackBenchConfig(workers=args.workers, camera=camera_model(args.camera, args.blur), people=args.people,
                               frames=40 if args.smoke else None, **given)
        summary = run_track_bench(cfg, Path(args.out), resume=getattr(args, "resume", False))
        for m, v in summary["occlusion_scenarios"].items():
            a = v["all"]
            print(f"{m:18s} occlusion scenarios: {a['pct_le_1px']:5.1f}% ≤1px {a['pct_le_2px']:5.1f}% ≤2px "
                  f"median {a['median_px']:.2f}px p95 {a['p95_px']:.1f}px | {a['median_ms']:.1f} ms median")
        for m, v in summary.get("target_set", {}).items():
            print(f"{m:18s} target set (hand-held walk_by, pause, partial): {v['all']['pct_le_2px']:5.1f}% ≤2px, "
                  f"{v['visible_lt_40']['pct_le_2px']:5.1f}% of frames with occlusion < 40 % ≤2px")
    else:
        from hvs_sim.bench.servo import ServoBenchConfig, run_servo_bench

        given = _given(args, ("methods", "trackers"), ("scenarios", "scenarios"), ("seeds", "seeds"))
        if args.episodes is not None:
            if args.seeds:
                raise ConfigError("give --episodes or --seeds for the servo benchmark, not both")
            given["episodes"] = args.episodes
        if args.smoke:
            print(SMOKE_NOTE)
            given = {"trackers": ("ground_truth", "hybrid"), "scenarios": ("walk_by",), "episodes": 1, **given}
        if args.extra_steps is not None and args.smoke:
            raise ConfigError("--extra-steps and --smoke disagree: a smoke run has its own 30 steps; give one")
        given.update(given_options(args, bench_loop_options()))  # the loop's settings the user gave, by field
        for field in ("damping", "extra_steps", "arm"):  # the benchmark's own servo-only settings
            if getattr(args, field) is not None:
                given[field] = getattr(args, field)
        if args.safety is not None:
            given["safety"] = args.safety == "on"
        suite = getattr(args, "suite_obj", None)
        if suite is not None:
            from hvs_sim.bench.suites import TILT_MAX_DEG

            given.update(extra_steps=suite.extra_steps, width=suite.width, height=suite.height,
                         tilt_deg=0.0 if suite.start == "4dof" else TILT_MAX_DEG, success_px=suite.success_px,
                         suite=suite.name, scenarios=suite.scenarios, seeds=tuple(args.seeds))
        cfg = ServoBenchConfig(workers=args.workers, camera=camera_model(args.camera, args.blur), people=args.people,
                               steps=30 if args.smoke else None, **given)
        summary = run_servo_bench(cfg, Path(args.out), resume=getattr(args, "resume", False))
        for s, per in summary["results"].items():
            for t, r in per.items():
                ok, reached = r["success"]["hvs_sim"], r["reached"]
                lo, hi = ok["ci95"]
                print(f"{s:8s} {t:24s} success {100 * ok['rate']:5.1f}% (95% CI {100 * lo:.0f}-{100 * hi:.0f}), "
                      f"reached {100 * reached['rate']:.0f}%, CNS {100 * r['success']['cns']['rate']:.0f}%, Felton "
                      f"{100 * r['success']['felton']['rate']:.0f}%, ViSP {100 * r['success']['visp']['rate']:.0f}%; "
                      f"median final {r['median_final_error_px']:.2f} px, {r['median_final_pose_error_mm']:.1f} mm"
                      + ("" if r.get("near_goal_switched") is None else
                         f"; switched to the near-goal template in {r['near_goal_switched']} of {r['episodes']}"))
        tp = summary.get("throughput")  # (an outside stand-in for the benchmark may not report it)
        med = tp and tp.get("median_episode_seconds")
        if med:
            print(f"{tp['episodes']} episodes in {tp['wall_seconds']:.0f} s with {tp['workers']} worker(s): "
                  f"{tp['episodes_per_hour']:.0f} episodes/hour; median episode {med['total']:.1f} s "
                  f"(start pose {med['start_pose']:.1f} s, steps {med['steps']:.1f} s)")
    if args.smoke:
        print(SMOKE_NOTE)
    return 0


def add_bench_parser(sub) -> None:
    from hvs_sim.control.laws.ibvs import TRACKED_6DOF_DAMPING
    from hvs_sim.scene.scenarios import PEOPLE_STYLES
    from hvs_sim.sensor import REALISTIC_PRESET, SENSOR_NAMES

    p = sub.add_parser("bench", formatter_class=HelpFormatter, help="benchmarks: tracking accuracy (track) or closed-loop convergence (servo)")
    p.add_argument("what", choices=("track", "servo", "suites", "compare"),
                   help="track | servo: run a benchmark; suites: list the versioned suites; compare A B: two servo "
                        "results of one suite, episode by episode")
    p.add_argument("paths", nargs="*", metavar="FOLDER", help="compare: the two result folders A B")
    p.add_argument("--suite", default=None, metavar="NAME",
                   help="a versioned suite (hvs-sim bench suites): its frozen scenarios, seeds, camera and rules; the "
                        "methods you name (default: its reference methods; quick always runs them beside yours); "
                        "quick: a look in ~2 minutes")
    p.add_argument("--out", default=None, help="output folder (default: out/bench_<what>)")
    p.add_argument("--resume", action="store_true",
                   help="track | servo: complete the interrupted run in --out, running only the episodes (sequences) "
                        "it has no record of in --out/episodes/; give the same options as that run (a different one "
                        "is refused); then the usual summary, table and figures")
    p.add_argument("--smoke", action="store_true", help="a tiny version that runs in about a minute (not a result)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace earlier results (summary.json, table.md, frames.csv, figures) in a non-empty --out")
    p.add_argument("--workers", type=int, default=1, help="processes (episodes and sequences are independent)")
    from hvs_sim.scene.scenarios import SCENARIO_NAMES
    from hvs_sim.tracking import TRACKER_NAMES

    p.add_argument("--methods", nargs="+", default=None, metavar="NAME",
                   help=f"trackers to compare: {', '.join(TRACKER_NAMES)}, or outside trackers (module:callable, "
                        "file.py:callable, registered or entry-point names); servo: TRACKER[:WARP][/CONTROLLER] or "
                        "policy=NAME, with ground_truth, none/dvs, and outside references in braces: "
                        "{mypkg.track:make}/{mypkg.law:make} (the hybrid_* are ablations, see "
                        "hvs_sim/tracking/registry.py; default: the benchmark's set)")
    p.add_argument("--damping", type=float, default=None,
                   help=f"servo only: damped pseudo-inverse, μ = damping × σ_max(L) (IBVSConfig.damping; default: {TRACKED_6DOF_DAMPING} for "
                        "tracked features on six DOF, else 0)")
    add_config_options(p, bench_loop_options(), "servo only, every episode's: ")  # LoopConfig's, as `run` has them
    p.add_argument("--extra-steps", type=int, default=None, metavar="N",
                   help="servo only: steps each episode runs past its scenario's end (default 60)")
    p.add_argument("--safety", choices=("on", "off"), default=None,
                   help="servo only: the loop's safety rule, the hold while it does not see (default on; off: an "
                        "ablation, never a servo to run on a robot; the workspace envelope stays on either way)")
    p.add_argument("--imagery", default="sim", choices=("sim", "natural"),
                   help="track only: sim = rendered scenes (default); natural = photos and procedural pictures moved "
                        "like a hand-held phone, with a drawn person (hvs_sim/bench/natural/)")
    p.add_argument("--scenarios", nargs="+", default=None,
                   metavar="NAME", help=f"scenarios: {', '.join(SCENARIO_NAMES)} (default: clear walk_by pause partial "
                   "two_people for track, clear walk_by pause for servo); with --imagery natural the kinds: clear walk_by pause "
                   "partial (default all)")
    p.add_argument("--sources", nargs="+", default=None, metavar="NAME",
                   help="--imagery natural only: pictures (default all of hvs_sim.bench.natural.NATURAL_SOURCES)")
    p.add_argument("--motion", default=None, choices=("hand", "tilt"),
                   help="--imagery natural only: how the phone moves: hand (default: drift, tremor, roll, a little "
                        "perspective) or tilt (also turned 10–13° out of the picture's plane and ±18 %% zoom)")
    p.add_argument("--mounts", nargs="+", default=None, metavar="MOUNT",
                   help="track only, sim imagery: handheld and/or arm (default both)")
    p.add_argument("--seeds", nargs="+", type=int, default=None,
                   help="sequence seeds (track) or episode seeds (servo), by hand (default: the test split's first "
                        "3 for track, 2 for natural imagery, 20 for servo)")
    p.add_argument("--episodes", type=int, default=None,
                   help="servo only: episodes per scenario and tracker, the first of the split's seeds (default 20)")
    from hvs_sim.bench.splits import BENCH_SPLITS, SPLIT_NAMES

    p.add_argument("--split", default=None, choices=SPLIT_NAMES,
                   help="which seeds: test (the default; published figures) or dev (what tuning may look at); "
                        + "; ".join(f"{k} {v.describe()}" for k, v in BENCH_SPLITS.items()))
    p.add_argument("--fresh", type=int, default=None, metavar="N",
                   help="N seeds drawn now from the system's entropy (episodes per scenario for servo; recorded in "
                        "summary.json as seeds_fresh)")
    add_blur_argument(p)
    p.add_argument("--camera", default=None, choices=SENSOR_NAMES,
                   help=f"camera model of every sequence/episode (default {REALISTIC_PRESET}; ideal = clean renders)")
    p.add_argument("--people", default=None, choices=PEOPLE_STYLES,
                   help="sim imagery: how the people look (default textured; plain = the flat figures of earlier "
                        "benchmarks)")
    from hvs_sim.scene.arms import ARM_NAMES

    p.add_argument("--arm", default=None, choices=ARM_NAMES,
                   help="servo only: the arm the camera rides on (default jaco; with --camera robot_cell, the camera a robot "
                        "carries)")
    p.set_defaults(func=cmd_bench)


def bench_loop_options() -> list[tuple[str, dict]]:
    """LoopConfig's command-line options that the servo benchmark sets for every episode: those ServoBenchConfig
    carries (servo.config.loop_options)."""
    import dataclasses

    from hvs_sim.bench.servo import ServoBenchConfig
    from hvs_sim.servo.config import loop_options

    carried = {f.name for f in dataclasses.fields(ServoBenchConfig)}
    return [(name, cli) for name, cli in loop_options() if name in carried]
