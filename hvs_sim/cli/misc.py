"""The small commands: `hvs-sim train` (the learned parts), `hvs-sim budget` (the pose bound), `hvs-sim dataset`
(offline-RL data) and `hvs-sim demo` (the README's run)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hvs_sim.cli.common import HelpFormatter, _target_overrides, stop_reason
from hvs_sim.cli.run import add_run_parser, cmd_run
from hvs_sim.cliargs import DEFAULT_TRACKER, near_goal_inset
from hvs_sim.errors import ConfigError
from hvs_sim.manifest import MANIFEST_NAME
from hvs_sim.outputs import fresh_out_dir, prepare_out_dir, write_atomic
from hvs_sim.scene.arms import DEFAULT_ARM

DEMO_OUTPUTS = ("run.json", "run_steps.csv", "run.rrd", "frames.png", "error.png")  # what `hvs-sim demo` writes
BUDGET_OUTPUTS = ("budget.json", "budget.md", "budget.png")
BUDGET_EPISODES = 3  # `hvs-sim budget`'s closed-loop episodes per camera: a handful, to set beside the prediction


def cmd_train(args) -> int:
    from hvs_sim.learn import train

    kwargs = {"out_dir": prepare_out_dir(args.out)}
    if args.what == "residual":
        cfg = train.ResidualTrainConfig(**{k: v for k, v in (("sequences", args.sequences), ("frames_per_sequence", args.frames),
                                                              ("epochs", args.epochs), ("seed", args.seed)) if v is not None})
        meta = train.train_residual(cfg, **kwargs)
        print(json.dumps({k: meta[k] for k in ("train_samples", "val_samples", "val_mse", "val_mse_without_residual", "seconds")}, indent=2))
    else:
        cfg = train.GRUTrainConfig(**{k: v for k, v in (("handheld_tracks", args.sequences), ("arm_tracks", args.sequences),
                                                        ("track_length", args.frames), ("epochs", args.epochs), ("seed", args.seed))
                                      if v is not None})
        meta = train.train_gru(cfg, **kwargs)
        print(json.dumps({k: meta[k] for k in ("train_windows", "val_windows", "val_position_error_px_after", "seconds")}, indent=2))
    return 0


def cmd_budget(args) -> int:
    """`hvs-sim budget`: the pose bound for each camera, what the loop's tracker does with it and what the closed loop
    reaches; a table, a JSON and a figure against standoff and size."""
    from hvs_sim.bench import budget as b

    if args.bound_only and args.episodes is not None:
        raise ConfigError("--bound-only runs no episodes: give --bound-only or --episodes, not both")
    args.episodes = BUDGET_EPISODES if args.episodes is None else args.episodes
    if args.episodes < 0:
        raise ConfigError(f"--episodes must be 0 or more, got {args.episodes}")
    from hvs_sim.outputs import check_apart, check_replaceable

    out = Path(args.out)
    files = {f"--out's {name}": out / name for name in BUDGET_OUTPUTS}
    inputs = [args.target_image] if args.target_image else []
    check_apart(inputs, files)  # an input named like an output is never replaced, nor removed by --overwrite
    check_replaceable(files, overwrite=True, root=out)
    if out.is_dir() and any(p.name != MANIFEST_NAME for p in out.iterdir()) and not args.overwrite:
        fresh_out_dir(out, False, ())  # said now, not after minutes of episodes
    scene = _target_overrides(args)
    if args.arm is not None:
        scene["arm"] = args.arm
    rows = [b.budget(cam, args.standoff, args.near_goal_inset, **scene)  # before --out is cleared
            for cam in dict.fromkeys(args.camera)]
    if not args.bound_only:
        done = []
        for i, row in enumerate(rows):
            def progress(k, cam=row.camera):
                print(f"  {cam}: closed-loop episode {k}/{args.episodes}", file=sys.stderr, flush=True)
            print(f"{row.camera} ({i + 1}/{len(rows)}): measuring the tracker at and around the goal"
                  + (f", then {args.episodes} servo episodes" if args.episodes else ""), file=sys.stderr, flush=True)
            done.append(b.estimate(row, args.episodes, progress, **scene))
        rows = done
    out = fresh_out_dir(args.out, args.overwrite, BUDGET_OUTPUTS, inputs=inputs)
    text = ("The pose bound (translation / rotation, 1-σ) on the template the loop tracks at the goal (template "
            "px; its inset, negative where the loop switches to a template grown beyond the target's outline):\n\n"
            + b.table(rows))
    if not args.bound_only:
        text += ("\nWhat the loop reaches (`hybrid:homography`, six DOF), along the two directions the pose is weakest "
                 "in (sideways shift traded against tilt), weakest first:\n\n" + b.estimate_table(rows))
    curves = b.figure(rows[0].camera, out / "budget.png", rows[0].near_goal,  # as budget read it ("off": None)
                      **{k: v for k, v in scene.items() if k != "target_width"})
    write_atomic(out / "budget.md", text)
    write_atomic(out / "budget.json", json.dumps({"rows": [r.row() for r in rows], "figure_camera": rows[0].camera,
                                                  "arm": args.arm or DEFAULT_ARM, "near_goal_inset_px": rows[0].near_goal,
                                                  "episodes": 0 if args.bound_only else args.episodes,
                                                  "figure_mm_by_width": curves, "note": b.__doc__.strip()}, indent=2))
    print(text, end="")
    print("The bound: no unbiased estimator reading these pixels does better. The prediction adds the tracker's bias "
          "at the goal and its error on clean views around it (docs/results.md, the pose bound).")
    print(f"results: {out}/ (budget.json, budget.md, budget.png)")
    return 0


def cmd_dataset(args) -> int:
    """`hvs-sim dataset`: the IBVS expert's episodes in the gym env, as a Minari dataset under --out."""
    from hvs_sim.bench.dataset import DatasetConfig, record

    config = DatasetConfig(episodes=args.episodes, seed=args.seed, scenario=args.scenario, camera=args.camera,
                           obs_mode=args.obs, max_steps=args.max_steps, dataset_id=args.dataset_id)
    try:
        summary = record(config, prepare_out_dir(args.out))
        code = 0
    except KeyboardInterrupt as exc:  # the finished episodes were written
        if not exc.args:
            raise
        summary, code = exc.args[0], 130
        print(f"hvs-sim: {stop_reason()}: the {summary['episodes']} finished episodes were written", file=sys.stderr)
    print(f"{summary['episodes']} episodes, {summary['steps']} steps, expert success {summary['success_rate']:.0%}; "
          f"start poses drawn again {sum(summary['start_draws']) - summary['episodes']} times (out of reach or view)")
    print(f"dataset: {summary['path']}\nread it: MINARI_DATASETS_PATH={args.out} python -c \"import minari; "
          f"print(minari.load_dataset('{config.dataset_id}'))\"")
    return code


def cmd_demo(args) -> int:
    from hvs_sim.outputs import check_replaceable

    parser = argparse.ArgumentParser(prog="hvs-sim")  # `run` alone: the demo is a run with fixed options
    add_run_parser(parser.add_subparsers(dest="command", required=True))
    out = prepare_out_dir(args.out)
    run_args = parser.parse_args(["run", "--scenario", "walk_by", "--tracker", DEFAULT_TRACKER, "--seed", "0",
                                  "--steps", "240", "--json", str(out / "run.json"), "--rrd", str(out / "run.rrd"),
                                  "--figures", str(out)])
    # every file of the demo is one the user did not name: an earlier demo's are replaced, anything else needs
    # --overwrite
    check_replaceable({f"--out's {name}": out / name for name in DEMO_OUTPUTS}, overwrite=args.overwrite, root=out,
                      hint=" or pass --overwrite")
    run_args.overwrite = args.overwrite
    return cmd_run(run_args)


def add_train_parser(sub) -> None:
    p = sub.add_parser("train", formatter_class=HelpFormatter, help="train the residual regressor or the GRU predictor on simulator data")
    p.add_argument("what", choices=("residual", "gru"))
    p.add_argument("--sequences", type=int, default=None, help="residual: rendered sequences; gru: tracks per kind")
    p.add_argument("--frames", type=int, default=None, help="residual: frames per sequence; gru: track length")
    p.add_argument("--epochs", type=int, default=None, help="(default: the training config's)")
    p.add_argument("--seed", type=int, default=None, help="(default 0)")
    p.add_argument("--out", default="out/weights",
                   help="output folder (default out/weights; --out assets/weights replaces the weights the package ships)")
    p.set_defaults(func=cmd_train)


def add_budget_parser(sub) -> None:
    from hvs_sim.scene.arms import ARM_NAMES
    from hvs_sim.sensor import SENSOR_NAMES

    p = sub.add_parser("budget", formatter_class=HelpFormatter,
                       help="what accuracy 6-DOF servoing can reach: the Cramér–Rao bound on the camera's pose at the "
                            "goal for a camera, a target and a standoff (hvs_sim/bench/budget.py)")
    p.add_argument("--camera", nargs="+", default=["phone_handheld"], choices=SENSOR_NAMES, metavar="NAME",
                   help=f"camera presets: {', '.join(SENSOR_NAMES)} (default phone_handheld)")
    p.add_argument("--target", default=None, help="a flag or natural texture name (default: the scenes' star_field)")
    p.add_argument("--target-image", default=None, help="any PNG/JPEG file as the target")
    p.add_argument("--target-width", type=float, default=None, help="the target's width in metres (default 0.15)")
    p.add_argument("--standoff", type=float, default=0.8, help="the camera's distance to the target at the goal (m)")
    p.add_argument("--arm", choices=ARM_NAMES, default=None, help="the arm the camera rides on (default jaco)")
    p.add_argument("--episodes", type=int, default=None,
                   help=f"closed-loop servo episodes per camera (the servo benchmark's clear start poses; 0 = none; "
                        f"default {BUDGET_EPISODES})")
    p.add_argument("--near-goal-inset", type=near_goal_inset, default="auto", metavar="auto|off|PX",
                   help="the template the loop switches to near the goal (as `run --near-goal-inset`; default auto): "
                        "the bound, the measurement and the episodes on it; off: the loop's one template")
    p.add_argument("--bound-only", action="store_true",
                   help="only the bound: no measurement of the tracker, no episodes (a second or two per camera)")
    p.add_argument("--out", default="out/budget", help="folder for budget.json, budget.md and budget.png")
    p.add_argument("--overwrite", action="store_true", help="replace earlier results in a non-empty --out")
    p.set_defaults(func=cmd_budget)


def add_demo_parser(sub) -> None:
    p = sub.add_parser("demo", formatter_class=HelpFormatter, help="the README's demo on built-in defaults (headless, offline)")
    p.add_argument("--out", default="out/demo", help="folder for run.json, run.rrd and the figures")
    p.add_argument("--overwrite", action="store_true",
                   help="replace files of those names that an earlier hvs-sim did not write (its own are replaced)")
    p.set_defaults(func=cmd_demo)


def add_dataset_parser(sub) -> None:
    from hvs_sim.bench.dataset import DATASET_ID, DATASET_OBS_MODES, DatasetConfig
    from hvs_sim.scene.scenarios import SCENARIO_NAMES
    from hvs_sim.sensor import SENSOR_NAMES

    d = DatasetConfig()
    p = sub.add_parser("dataset", formatter_class=HelpFormatter,
                       help="record the IBVS expert driving the gym env from the servo benchmark's start poses, as a "
                            "Minari dataset for offline RL or behaviour cloning (hvs_sim/bench/dataset.py)")
    p.add_argument("--episodes", type=int, default=d.episodes, help="episodes to record")
    p.add_argument("--seed", type=int, default=d.seed, help="episode k uses seed SEED + k")
    p.add_argument("--scenario", default=d.scenario, choices=SCENARIO_NAMES, metavar="NAME",
                   help=f"one of: {', '.join(SCENARIO_NAMES)}")
    p.add_argument("--camera", default=d.camera, choices=SENSOR_NAMES, metavar="NAME",
                   help=f"camera preset: {', '.join(SENSOR_NAMES)}")
    p.add_argument("--obs", default=d.obs_mode, choices=DATASET_OBS_MODES,
                   help="the env's observation (image modes: 160×120 frames, far larger files)")
    p.add_argument("--max-steps", type=int, default=d.max_steps, help="an episode not converged by then is truncated")
    p.add_argument("--dataset-id", default=DATASET_ID, help="Minari's namespace/name-vN")
    p.add_argument("--out", default="out/datasets", help="a Minari datasets root (MINARI_DATASETS_PATH)")
    p.set_defaults(func=cmd_dataset)
