"""`hvs-sim run`: one closed-loop servo run (render -> track -> IBVS -> arm), its options and their checks."""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import sys
from pathlib import Path

from hvs_sim.cli.common import EXIT_OUTPUT_FAILED, HelpFormatter, _add_scene_args, _scenario_from_args
from hvs_sim.cliargs import DEFAULT_TRACKER, add_config_options, add_settings_option, given_options, parse_settings
from hvs_sim.errors import ConfigError
from hvs_sim.outputs import check_output_file, prepare_out_dir


def cmd_run(args) -> int:
    from hvs_sim.runner import run_episode
    from hvs_sim.servo.config import LoopConfig, loop_options

    if args.steps < 1:
        raise ConfigError(f"--steps must be >= 1, got {args.steps}")
    from hvs_sim.outputs import check_apart
    from hvs_sim.runner import steps_csv_path

    for flag in ("json", "rrd", "mcap", "figures"):
        if getattr(args, flag) is not None and not str(getattr(args, flag)).strip():
            raise ConfigError(f"--{flag} is empty; give a {'folder' if flag in ('mcap', 'figures') else 'file name'}")
    if args.mcap and Path(args.mcap).exists():
        raise ConfigError(f"--mcap {args.mcap} exists: a ROS 2 bag is a new folder; give a path that does not exist")
    check_apart([p for p in (args.target_image, args.wall_images) if p],
                {"--json": args.json and Path(args.json), "--json's steps CSV": args.json and steps_csv_path(args.json),
                 "--rrd": args.rrd and Path(args.rrd), "--mcap": args.mcap and Path(args.mcap),
                 **{f"--figures' {name}": args.figures and Path(args.figures) / name
                    for name in ("frames.png", "error.png")}})
    for flag, path in (("--json", args.json), ("--rrd", args.rrd)):
        check_output_file(path, flag)
    check_sidecars(args, getattr(args, "overwrite", False))
    if args.spawn:
        _check_viewer()
    if args.figures:
        prepare_out_dir(args.figures, "--figures")
    settings = parse_settings(args.set)  # checked where the loop builds its tracker, before the scene
    if args.tracker is None:  # a policy or a law on the images needs no tracker; the others the default one
        args.tracker = "none" if args.policy or args.controller == "dvs" else DEFAULT_TRACKER
    if args.warp is not None:
        if args.tracker in ("ground_truth", "none"):
            raise ConfigError(f"--warp selects a tracker's warp model; {args.tracker} has none (ground_truth features "
                              "are already perspective corners): leave --warp out")
        if "warp" in settings and settings["warp"] != args.warp:
            raise ConfigError(f"--warp {args.warp} and --set warp={settings['warp']} disagree: give one")
        settings["warp"] = args.warp
    scenario = _scenario_from_args(args)
    if args.start_offset is not None:
        scenario = dataclasses.replace(scenario, start_offset=parse_start_offset(args.start_offset))
    config = LoopConfig(steps=args.steps, controller=args.controller, policy=args.policy, evaluate=not args.no_eval,
                        pipeline=args.pipeline,
                        keep_frames=bool(args.rrd or args.spawn or args.figures or args.mcap),
                        **given_options(args, loop_options()))
    summary, _ = run_episode(scenario, args.tracker, config, rrd=args.rrd, spawn=args.spawn, json_path=args.json,
                             tracker_settings=settings, figures=args.figures, mcap=args.mcap)
    # the pose error over the controlled DOFs: what convergence and error.png judge (all axes are in --json)
    brief = {k: summary[k] for k in ("converged", "held_to_end", "steps_to_converge", "final_error_px",
                                     "final_controlled_pose_error_mm", "final_controlled_pose_error_deg",
                                     "controlled_dofs",
                                     "max_error_px_during_occlusion", "lost_steps", "predict_steps", "fault_steps",
                                     "held_steps", "steps_per_second")}
    print(json.dumps(brief, indent=2))
    if not summary["held_to_end"]:
        print(f"not converged at the end: {summary['not_converged_because']}")
    if "recording_error" in summary:
        print(f"hvs-sim: {summary['recording_error']}", file=sys.stderr)
    if summary["held_steps"]:
        why = ", ".join(f"{n} {k}" for k, n in summary["held_because"].items())
        print(f"the safety rule held the arm for {summary['held_steps']} step(s) while it could not trust what it saw "
              f"({why})")
    if summary["aborted"]:
        print(f"aborted: {summary['aborted']}")
    if summary["faults"]:
        print(f"{summary['fault_steps']} step(s) faulted, the arm held for them: " + "; ".join(summary["faults"][:3]))
    if args.json:
        print(f"summary: {args.json}")
    if args.figures:
        print("figures: " + ", ".join(summary["figures"]))
    if "recording_error" in summary:
        return EXIT_OUTPUT_FAILED
    if args.rrd:
        viewer = "rerun" if shutil.which("rerun") else str(Path(sys.executable).parent / "rerun")
        print(f"recording: {args.rrd}  (open it with: {viewer} {args.rrd})")
    return 0


def check_sidecars(args, overwrite: bool) -> None:
    """The files run writes that the user did not name (the steps CSV beside --json, the figures in --figures) may
    replace only what hvs_sim wrote there; none of its outputs is written through a symbolic link."""
    from hvs_sim.outputs import check_name_length, check_replaceable
    from hvs_sim.runner import steps_csv_path

    named = {"--json": args.json and Path(args.json), "--rrd": args.rrd and Path(args.rrd)}
    sidecars = {"--json's steps CSV": args.json and steps_csv_path(args.json),
                **{f"--figures' {name}": args.figures and Path(args.figures) / name for name in ("frames.png", "error.png")}}
    if args.json:
        check_name_length(steps_csv_path(args.json), "--json's steps CSV")
    check_replaceable(named, overwrite=True)  # the user named them: replaced, but not through a link
    check_replaceable(sidecars, overwrite=overwrite, root=args.figures or None,
                      hint=(" or pass --overwrite" if hasattr(args, "overwrite") else ", or give another --json / "
                            "--figures"))


def parse_start_offset(text: str) -> tuple[float, ...]:
    """"dx,dy,dz,roll,pitch,yaw" (metres, degrees) → the scenario's start_offset (metres, radians)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"--start-offset takes six numbers dx,dy,dz,roll,pitch,yaw (metres, degrees), got {text!r}")
    return tuple(values[:3]) + tuple(math.radians(v) for v in values[3:])


def _check_viewer() -> None:
    """--spawn opens rerun's viewer window: refuse now, not after the run, where it cannot open."""
    import os

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError("--spawn opens the rerun viewer window, but this machine has no display (DISPLAY and "
                          "WAYLAND_DISPLAY are unset). Save a recording with --rrd out/run.rrd and open it where there "
                          "is a screen: rerun out/run.rrd")
    venv_bin = str(Path(sys.executable).parent)
    if shutil.which("rerun") is None and shutil.which("rerun", path=venv_bin):
        os.environ["PATH"] = venv_bin + os.pathsep + os.environ.get("PATH", "")  # rerun-sdk's viewer, not activated
    if shutil.which("rerun") is None:
        raise ConfigError("--spawn needs the rerun viewer (the `rerun` command of rerun-sdk) on PATH; install "
                          "rerun-sdk in this environment, or save a recording with --rrd and open it elsewhere")


def add_run_parser(sub) -> None:
    p = sub.add_parser("run", formatter_class=HelpFormatter, help="closed-loop servo run: render -> track -> IBVS -> arm")
    _add_scene_args(p, mount=False)
    from hvs_sim.tracking import TRACKER_NAMES

    loop_trackers = ("ground_truth", "none", *TRACKER_NAMES)  # hvs_sim.servo.config.LOOP_TRACKERS, without importing MuJoCo
    p.add_argument("--tracker", default=None, metavar="NAME",
                   help=f"one of: {', '.join(loop_trackers)}, or an outside tracker: a registered or entry-point name, "
                        f"package.module:callable or path/to/file.py:callable (default {DEFAULT_TRACKER}; none with "
                        "--policy or --controller dvs; the hybrid_* names are its ablations, "
                        "hvs_sim/tracking/registry.py)")
    p.add_argument("--steps", type=int, default=240, help="control steps at 30 Hz")
    from hvs_sim.control.laws.ibvs import CONTROLLERS
    from hvs_sim.servo.config import loop_options
    from hvs_sim.tracking.warp import WARPS

    p.add_argument("--warp", default=None, choices=WARPS,
                   help="the tracker's warp model (default: the tracker's, similarity); homography gives perspective "
                        "corners, and the controller then commands all six DOF")
    p.add_argument("--controller", default="ibvs", metavar="LAW",
                   help=f"the servo law: {', '.join(CONTROLLERS)} (dvs: photometric, no tracker), or an outside law "
                        "(a registered or entry-point name, package.module:callable, path/to/file.py:callable)")
    p.add_argument("--policy", default=None, metavar="NAME",
                   help="an outside policy (image + joints → camera twist) in place of tracker and law: a registered "
                        "or entry-point name, package.module:callable or path/to/file.py:callable")
    add_config_options(p, loop_options())  # LoopConfig's own: --template-from, --roi-inset, --near-goal-*, ...
    p.add_argument("--pipeline", action="store_true",
                   help="track each frame in a second thread while the physics steps and the next frame renders: "
                        "about the longer of the two per step instead of their sum, at one frame of actuation latency")
    p.add_argument("--no-eval", action="store_true",
                   help="skip the evaluation render (the true occlusion, one segmentation render a step); errors "
                        "and pose errors, which need no render, are still recorded. Control never reads ground truth (the "
                        "target's corners in the first frame, which place the template or seed it, are the user's "
                        "marking)")
    p.add_argument("--start-offset", default=None, metavar="DX,DY,DZ,ROLL,PITCH,YAW",
                   help="start pose relative to the reference pose, camera frame (metres, degrees; dz > 0 is "
                        "towards the target); write --start-offset=-0.03,... when the first value is negative; "
                        "default: the scenario's (0.03,-0.02,0.06,6,0,0)")
    p.add_argument("--json", default=None, help="write the run summary here")
    p.add_argument("--rrd", default=None, help="save a rerun recording here")
    p.add_argument("--mcap", default=None, metavar="DIR",
                   help="also write a ROS 2 bag (MCAP) into this new folder: image, camera info, joint states, tf, "
                        "commanded twist, corners (hvs_sim/viz/rosbag.py)")
    p.add_argument("--spawn", action="store_true", help="open the rerun viewer")
    add_settings_option(p)
    p.add_argument("--figures", default=None, metavar="DIR",
                   help="write frames.png (4 frames with tracked/true/desired outlines) and error.png here")
    p.set_defaults(func=cmd_run)
