"""The `hvs-sim` command."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shutil
import sys
from pathlib import Path

from hvs_sim.cliargs import DEFAULT_TRACKER, add_settings_option, parse_settings
from hvs_sim.errors import ConfigError, HvsError, OutputError
from hvs_sim.outputs import check_output_file, fresh_out_dir, prepare_out_dir, write_atomic


def _target_overrides(args) -> dict:
    """The target that --target, --target-image and --target-width name, as make_scenario keywords (run, scene,
    budget)."""
    from hvs_sim.scene.flag_art import FLAG_NAMES
    from hvs_sim.scene.textures import NATURAL_TEXTURES

    overrides = {}
    if args.target:
        if args.target not in FLAG_NAMES + NATURAL_TEXTURES:
            raise ConfigError(f"unknown target {args.target!r}; accepted: a flag ({', '.join(FLAG_NAMES)}) or a "
                              f"natural texture ({', '.join(NATURAL_TEXTURES)}); or --target-image PATH")
        overrides["target_flag" if args.target in FLAG_NAMES else "target_texture"] = args.target
    if args.target and args.target_image:
        raise ConfigError("give --target NAME or --target-image PATH, not both")
    if args.target or args.target_image:  # what the user names replaces the preset's target, whatever kind it was
        overrides.setdefault("target_texture", None)
        overrides["target_image"] = args.target_image
    if args.target_width is not None:
        overrides["target_width"] = args.target_width
    return overrides


def _scenario_from_args(args):
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    overrides = {"camera": CameraConfig(width=args.width, height=args.height, fovy=args.fovy, sensor=args.camera,
                                        multisample=args.multisample), **_target_overrides(args)}
    if args.wall_images and not args.wall:
        overrides["wall"] = "flags"  # the folder replaces the preset's wall set
    for key in ("wall", "wall_images", "people"):
        if getattr(args, key) is not None:
            overrides[key] = getattr(args, key)
    if getattr(args, "shadows", False):
        overrides["shadows"] = True
    return make_scenario(args.scenario, mount=getattr(args, "mount", "arm"), seed=args.seed, **overrides)


def _add_scene_args(p: argparse.ArgumentParser, mount: bool) -> None:
    from hvs_sim.camera_model import SENSOR_NAMES
    from hvs_sim.scene.scenarios import (
        DEFAULT_MULTISAMPLE,
        MULTISAMPLE_CHOICES,
        PEOPLE_STYLES,
        SCENARIO_NAMES,
        WALL_SETS,
    )

    p.add_argument("--scenario", default="walk_by", help=f"one of: {', '.join(SCENARIO_NAMES)} (hvs-sim scenes --list)")
    if mount:  # `run` is closed-loop: its camera is on the arm, so it offers no --mount
        p.add_argument("--mount", default="handheld", choices=("handheld", "arm"), help="where the camera is")
    p.add_argument("--seed", type=int, default=0, help="seeds the person, the shake, the sensor noise")
    p.add_argument("--camera", default="ideal", choices=SENSOR_NAMES,
                   help="camera model: exposure, blur, noise, JPEG, distortion (default: ideal = clean renders)")
    p.add_argument("--target", default=None, help="target: a flag name or a natural texture name (default: the "
                   "scenario's, star_field)")
    p.add_argument("--target-image", default=None, help="any PNG/JPEG file as the target (aspect ratio kept)")
    p.add_argument("--target-width", type=float, default=None, help="physical width of the target in metres (default 0.15)")
    p.add_argument("--wall", default=None, choices=WALL_SETS, help="what fills the wall beside the target (default flags)")
    p.add_argument("--wall-images", default=None, help="a folder of images to fill the wall (centre-cropped to 3:2)")
    p.add_argument("--people", default=None, choices=PEOPLE_STYLES,
                   help="how the people look (default textured; plain = the flat figures of earlier versions)")
    p.add_argument("--width", type=int, default=640, help="image width in pixels (64-4096)")
    p.add_argument("--height", type=int, default=480, help="image height in pixels (64-4096)")
    p.add_argument("--fovy", type=float, default=45.0, help="vertical field of view in degrees")
    p.add_argument("--multisample", type=int, default=DEFAULT_MULTISAMPLE, choices=MULTISAMPLE_CHOICES,
                   help="anti-aliasing samples per pixel of the render (0 = off, about half the render time)")


def cmd_scene(args) -> int:
    import cv2
    import numpy as np

    from hvs_sim.render.sequence import iterate_sequence, write_sequence

    if args.frames is not None and args.frames < 1:
        raise ConfigError(f"--frames must be >= 1, got {args.frames}")
    from hvs_sim.outputs import check_apart

    check_apart([p for p in (args.target_image, args.wall_images) if p], {"--out": Path(args.out) / "scenario.json"})
    scenario = _scenario_from_args(args)
    out = fresh_out_dir(args.out, args.overwrite, SCENE_OUTPUTS)
    meta = write_sequence(scenario, out, fmt=args.format, n_frames=args.frames)
    # a preview: the first frame with the ground-truth outline and centre
    frame, gt = next(iterate_sequence(scenario, 1))
    bgr = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
    cv2.polylines(bgr, [np.round(gt.corners * 16).astype(np.int32)], True, (0, 255, 0), 1, cv2.LINE_AA, shift=4)
    cv2.drawMarker(bgr, tuple(np.round(gt.center).astype(int)), (0, 255, 0), cv2.MARKER_CROSS, 12, 1)
    if not cv2.imwrite(str(out / "preview.png"), bgr):
        raise OutputError(f"could not write {out / 'preview.png'} (disk full or folder not writable)")
    print(json.dumps({"out": str(out), "frames": meta["frames"], "peak_occlusion": round(meta["peak_occlusion"], 3)}))
    return 0


def cmd_run(args) -> int:
    from hvs_sim.loop import LoopConfig
    from hvs_sim.runner import run_episode

    if args.steps < 1:
        raise ConfigError(f"--steps must be >= 1, got {args.steps}")
    from hvs_sim.outputs import check_apart
    from hvs_sim.runner import steps_csv_path

    if args.mcap and Path(args.mcap).exists():
        raise ConfigError(f"--mcap {args.mcap} exists: a ROS 2 bag is a new folder; give a path that does not exist")
    check_apart([p for p in (args.target_image, args.wall_images) if p],
                {"--json": args.json and Path(args.json), "--json's steps CSV": args.json and steps_csv_path(args.json),
                 "--rrd": args.rrd and Path(args.rrd), "--mcap": args.mcap and Path(args.mcap),
                 **{f"--figures' {name}": args.figures and Path(args.figures) / name
                    for name in ("frames.png", "error.png")}})
    for flag, path in (("--json", args.json), ("--rrd", args.rrd)):
        check_output_file(path, flag)
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
                        template_from=args.template_from,
                        roi_inset_px=args.roi_inset, goal_frames=args.goal_frames,
                        feature_filter=args.feature_filter)
    summary, _ = run_episode(scenario, args.tracker, config, rrd=args.rrd, spawn=args.spawn, json_path=args.json,
                             tracker_settings=settings, figures=args.figures, mcap=args.mcap)
    brief = {k: summary[k] for k in ("converged", "held_to_end", "steps_to_converge", "final_error_px",
                                     "final_pose_error_mm", "final_pose_error_deg", "controlled_dofs",
                                     "max_error_px_during_occlusion", "lost_steps", "predict_steps", "fault_steps",
                                     "steps_per_second")}
    print(json.dumps(brief, indent=2))
    if not summary["held_to_end"]:
        print(f"not converged at the end: {summary['not_converged_because']}")
    if "recording_error" in summary:
        print(f"hvs-sim: {summary['recording_error']}", file=sys.stderr)
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


def _provenance(argv: list[str]) -> dict:
    import subprocess

    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True,
                                cwd=Path(__file__).parent).stdout.strip()
    except (OSError, subprocess.SubprocessError):  # no git, or not a checkout
        commit = "unknown"
    return {"command": "hvs-sim " + " ".join(argv), "commit": commit}


def _check_bench_options(args) -> None:
    """Refuse options that do not apply to the chosen benchmark, rather than ignoring them."""
    if args.what == "servo":
        for flag, value in (("--imagery natural", args.imagery == "natural"), ("--sources", args.sources),
                            ("--mounts", args.mounts), ("--motion", args.motion)):
            if value:
                raise ConfigError(f"{flag} applies to `bench track` only (the servo benchmark's camera is on the arm)")
        return
    for flag, value in (("--episodes", args.episodes), ("--damping", args.damping),
                        ("--template-from", args.template_from), ("--roi-inset", args.roi_inset),
                        ("--goal-frames", args.goal_frames), ("--feature-filter", args.feature_filter),
                        ("--extra-steps", args.extra_steps)):
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
    summary = run_natural_bench(cfg, Path(args.out))
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
SCENE_OUTPUTS = ("frames.mp4", "frames/*.png", "ground_truth.csv", "ground_truth.npz", "scenario.json", "preview.png")


def cmd_bench(args) -> int:
    if args.what == "suites":
        from hvs_sim.bench.suites import describe

        print(describe(), end="")
        return 0
    if args.what == "compare":
        return cmd_bench_compare(args)
    if args.paths:
        raise ConfigError(f"`bench {args.what}` takes no positional folders (got {args.paths}); `bench compare A B` does")
    if args.suite:
        _apply_suite(args)
    elif args.camera is None:
        from hvs_sim.camera_model import REALISTIC_PRESET

        args.camera = REALISTIC_PRESET
    _check_bench_options(args)
    fresh_out_dir(args.out, args.overwrite, BENCH_OUTPUTS)
    if args.what == "track" and args.imagery == "natural":
        status = cmd_bench_natural(args)
    else:
        status = _cmd_bench_sim(args)
    path = Path(args.out) / "summary.json"
    data = json.loads(path.read_text())
    data["provenance"] = _provenance(args.argv)
    write_atomic(path, json.dumps(data, indent=2))
    print(f"results: {args.out}/ (summary.json, table.md, figures)")
    return status


def _apply_suite(args) -> None:
    """--suite NAME: the suite's frozen settings; the methods named run alone (beside the reference methods in a suite
    `with_reference`, or those alone when none is named), and any option that would change the suite's episodes is
    refused."""
    from hvs_sim.bench.suites import get_suite

    suite = get_suite(args.suite, args.what)
    for flag, value in (("--smoke", args.smoke), ("--scenarios", args.scenarios), ("--seeds", args.seeds),
                        ("--episodes", args.episodes), ("--camera", args.camera), ("--people", args.people),
                        ("--extra-steps", args.extra_steps), ("--mounts", args.mounts),
                        ("--imagery natural", args.imagery == "natural")):
        if value:
            raise ConfigError(f"{flag} changes what suite {suite.name} fixes (its scenarios, seeds, camera, people "
                              "and steps): leave it out, or run without --suite")
    named = list(args.methods or [])
    args.methods = list(dict.fromkeys([*suite.methods, *named] if suite.with_reference or not named else named))
    args.scenarios, args.seeds, args.camera = list(suite.scenarios), list(suite.seeds), suite.camera
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
    out = fresh_out_dir(args.out, args.overwrite, ("compare.json", "compare.md", "compare.png"))
    table = compare_table(result)
    write_atomic(out / "compare.json", json.dumps(result, indent=2))
    write_atomic(out / "compare.md", table)
    compare_figure(result, out / "compare.png")
    print(table, end="")
    print(f"results: {out}/ (compare.json, compare.md, compare.png)")
    return 0


SMOKE_NOTE = "SMOKE RUN: checks that the pipeline runs end to end; the figures it prints are NOT a result"


def _given(args, *names) -> dict:
    """The bench options the user gave, as config fields (tuples)."""
    return {field: tuple(getattr(args, opt)) for opt, field in names if getattr(args, opt)}


def _cmd_bench_sim(args) -> int:
    args.people = args.people or "textured"
    if args.what == "track":
        from hvs_sim.bench.track import METHODS, TrackBenchConfig, run_track_bench

        given = _given(args, ("methods", "methods"), ("scenarios", "scenarios"), ("mounts", "mounts"), ("seeds", "seeds"))
        if args.smoke:  # small defaults; what the user names is honoured
            print(SMOKE_NOTE)
            given = {"methods": METHODS, "scenarios": ("walk_by",), "mounts": ("handheld",), "seeds": (100,), **given}
        cfg = TrackBenchConfig(workers=args.workers, camera=args.camera, people=args.people,
                               frames=40 if args.smoke else None, **given)
        summary = run_track_bench(cfg, Path(args.out))
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
        for opt, field in (("damping", "damping"), ("template_from", "template_from"), ("roi_inset", "roi_inset_px"),
                           ("goal_frames", "goal_frames"), ("feature_filter", "feature_filter"),
                           ("extra_steps", "extra_steps")):  # servo-only settings the user gave
            if getattr(args, opt) is not None:
                given[field] = getattr(args, opt)
        suite = getattr(args, "suite_obj", None)
        if suite is not None:
            from hvs_sim.bench.suites import TILT_MAX_DEG

            given.update(extra_steps=suite.extra_steps, width=suite.width, height=suite.height,
                         tilt_deg=0.0 if suite.start == "4dof" else TILT_MAX_DEG, success_px=suite.success_px,
                         suite=suite.name, scenarios=suite.scenarios, seeds=suite.seeds)
        cfg = ServoBenchConfig(workers=args.workers, camera=args.camera, people=args.people,
                               steps=30 if args.smoke else None, **given)
        summary = run_servo_bench(cfg, Path(args.out))
        for s, per in summary["results"].items():
            for t, r in per.items():
                ok, reached = r["success"]["hvs_sim"], r["reached"]
                lo, hi = ok["ci95"]
                print(f"{s:8s} {t:24s} success {100 * ok['rate']:5.1f}% (95% CI {100 * lo:.0f}-{100 * hi:.0f}), "
                      f"reached {100 * reached['rate']:.0f}%, CNS {100 * r['success']['cns']['rate']:.0f}%, Felton "
                      f"{100 * r['success']['felton']['rate']:.0f}%, ViSP {100 * r['success']['visp']['rate']:.0f}%; "
                      f"median final {r['median_final_error_px']:.2f} px, {r['median_final_pose_error_mm']:.1f} mm")
    if args.smoke:
        print(SMOKE_NOTE)
    return 0


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


def cmd_budget(args) -> int:
    """`hvs-sim budget`: the pose bound for each camera, a table, a JSON and a figure against standoff and size."""
    from hvs_sim.bench import budget as b

    scene = _target_overrides(args)
    rows = [b.budget(cam, args.standoff, **scene) for cam in dict.fromkeys(args.camera)]  # before --out is cleared
    out = fresh_out_dir(args.out, args.overwrite, ("budget.json", "budget.md", "budget.png"))
    text = b.table(rows)
    curves = b.figure(rows[0].camera, out / "budget.png", **{k: v for k, v in scene.items() if k != "target_width"})
    write_atomic(out / "budget.md", text)
    write_atomic(out / "budget.json", json.dumps({"rows": [r.row() for r in rows], "figure_camera": rows[0].camera,
                                                  "figure_mm_by_width": curves, "note": b.__doc__.strip()}, indent=2))
    print(text, end="")
    print("A bound: no unbiased estimator reading these pixels does better; biases (exposure changes between the goal "
          "image and the frames, the target's relief) come on top.")
    print(f"results: {out}/ (budget.json, budget.md, budget.png)")
    return 0


def cmd_scenes(args) -> int:
    """List what a scene can be built from: scenario presets, camera presets, wall sets, targets."""
    from hvs_sim.camera_model import SENSOR_PRESETS
    from hvs_sim.scene.flag_art import FLAG_NAMES
    from hvs_sim.scene.scenarios import SCENARIO_NAMES, WALL_SETS, make_scenario
    from hvs_sim.scene.textures import NATURAL_TEXTURES, TEXTURE_SETS

    print("scenarios (--scenario):")
    for name in SCENARIO_NAMES:
        sc = make_scenario(name)
        people = ", ".join(f"{o.kind} at {o.t_cross:g} s" for o in sc.occluders) or "nobody"
        print(f"  {name:16s} {sc.duration:4.1f} s  target {sc.target_label:14s} wall {sc.wall:12s} people: {people}")
    print("camera presets (--camera):")
    for name, m in SENSOR_PRESETS.items():
        print(f"  {name:16s} " + ("clean renders, every effect off" if m.is_ideal else
              f"exposure {m.exposure_ms:g} ms, {m.white_e:g} e- from white, read noise {m.read_noise_e:g} e-, "
              f"AE target {m.ae_target:g}, JPEG q{m.jpeg_quality}, light dim {m.light_dim:g} / flicker {m.light_flicker:g}"
              + (f", distortion k1 {m.distortion[0]:g}" if m.distortion else "")))
    print("wall sets (--wall): " + ", ".join(WALL_SETS))
    for name, members in TEXTURE_SETS.items():
        print(f"  {name:16s} {', '.join(members)}")
    print("targets (--target): flags " + ", ".join(FLAG_NAMES))
    print("                    natural textures " + ", ".join(NATURAL_TEXTURES))
    print("                    or any image file: --target-image PATH [--target-width M]")
    return 0


def cmd_demo(args) -> int:
    parser = build_parser()
    out = Path(args.out)
    return cmd_run(parser.parse_args(["run", "--scenario", "walk_by", "--tracker", DEFAULT_TRACKER, "--seed", "0",
                                      "--steps", "240", "--json", str(out / "run.json"), "--rrd", str(out / "run.rrd"),
                                      "--figures", str(out)]))


class HelpFormatter(argparse.HelpFormatter):
    """Every option's help shows its default, unless the help already says it."""

    def _get_help_string(self, action):
        text = action.help or ""
        d = action.default
        if "default" not in text and d is not None and d is not False and d != argparse.SUPPRESS and action.option_strings:
            text += " (default: %(default)s)"
        return text


def build_parser() -> argparse.ArgumentParser:
    from hvs_sim import __version__

    parser = argparse.ArgumentParser(prog="hvs-sim", description="Occlusion-robust visual servoing simulator",
                                     formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"hvs-sim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("scene", formatter_class=HelpFormatter, help="render a scenario open-loop to frames + ground truth")
    _add_scene_args(p, mount=True)
    p.add_argument("--out", default="out/scene", help="output folder")
    p.add_argument("--format", choices=("mp4", "png"), default="mp4", help="frames as one video or one PNG each")
    p.add_argument("--frames", type=int, default=None, help="number of frames (default: the scenario's duration)")
    p.add_argument("--shadows", action="store_true", help="cast shadows (about 5x slower on a CPU)")
    p.add_argument("--overwrite", action="store_true", help="replace earlier results in a non-empty --out")
    p.set_defaults(func=cmd_scene)

    p = sub.add_parser("run", formatter_class=HelpFormatter, help="closed-loop servo run: render -> track -> IBVS -> arm")
    _add_scene_args(p, mount=False)
    from hvs_sim.tracking import TRACKER_NAMES

    loop_trackers = ("ground_truth", "none", *TRACKER_NAMES)  # hvs_sim.loop.LOOP_TRACKERS, without importing MuJoCo
    p.add_argument("--tracker", default=None, metavar="NAME",
                   help=f"one of: {', '.join(loop_trackers)}, or an outside tracker: a registered or entry-point name, "
                        f"package.module:callable or path/to/file.py:callable (default {DEFAULT_TRACKER}; none with "
                        "--policy or --controller dvs; the hybrid_* names are its ablations, "
                        "hvs_sim/tracking/registry.py)")
    p.add_argument("--steps", type=int, default=240, help="control steps at 30 Hz")
    from hvs_sim.control.feature_filter import FEATURE_FILTER_ALPHA
    from hvs_sim.control.ibvs import CONTROLLERS, GOAL_FRAMES, TEMPLATE_VIEWS, TRACKED_6DOF_DAMPING
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
    p.add_argument("--template-from", default=None, choices=TEMPLATE_VIEWS,
                   help="where the tracker's template comes from: the run's first frame, or the goal image (the camera "
                        "at the reference pose, people left out: teach-by-showing), the tracker then seeded at the "
                        "target's corners in the first frame (default: goal for a tracker on six DOF, i.e. --warp "
                        "homography; else start)")
    p.add_argument("--roi-inset", type=int, default=None, metavar="PX",
                   help="cut the template this many pixels inside the target's outline, which renders differently "
                        "from view to view (default: 8 with a goal template, fewer for a target too small for it; 0 "
                        "with a start template)")
    p.add_argument("--feature-filter", type=float, default=None, metavar="ALPHA",
                   help="α of the filter that blends the tracked corners with where the camera's own motion (the "
                        f"joints' forward kinematics) carries the last estimate, in [0, 1]; 0 = off (default "
                        f"{FEATURE_FILTER_ALPHA} for tracked corners on six DOF, else off)")
    p.add_argument("--goal-frames", type=int, default=None, metavar="N",
                   help="frames of the still goal view averaged into the goal image, as a user teaching the goal "
                        f"averages a few grabs: the camera's noise falls ~√N (default {GOAL_FRAMES} with a goal "
                        "template; refused with a start template)")
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

    p = sub.add_parser("train", formatter_class=HelpFormatter, help="train the residual regressor or the GRU predictor on simulator data")
    p.add_argument("what", choices=("residual", "gru"))
    p.add_argument("--sequences", type=int, default=None, help="residual: rendered sequences; gru: tracks per kind")
    p.add_argument("--frames", type=int, default=None, help="residual: frames per sequence; gru: track length")
    p.add_argument("--epochs", type=int, default=None, help="(default: the training config's)")
    p.add_argument("--seed", type=int, default=None, help="(default 0)")
    p.add_argument("--out", default="out/weights",
                   help="output folder (default out/weights; --out assets/weights replaces the weights the package ships)")
    p.set_defaults(func=cmd_train)

    from hvs_sim.camera_model import REALISTIC_PRESET, SENSOR_NAMES
    from hvs_sim.scene.scenarios import PEOPLE_STYLES

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
    p.add_argument("--template-from", default=None, choices=TEMPLATE_VIEWS,
                   help="servo only: where the tracker's template comes from (as `run --template-from`; default: goal "
                        "for tracked corners on six DOF, else start)")
    p.add_argument("--extra-steps", type=int, default=None, metavar="N",
                   help="servo only: steps each episode runs past its scenario's end (default 60)")
    p.add_argument("--roi-inset", type=int, default=None, metavar="PX",
                   help="servo only: cut the template this many pixels inside the target's outline (as `run "
                        "--roi-inset`; default: 8 with a goal template, 0 with a start one)")
    p.add_argument("--goal-frames", type=int, default=None, metavar="N",
                   help=f"servo only: frames averaged into the goal image (as `run --goal-frames`; default {GOAL_FRAMES} with a goal "
                        "template)")
    p.add_argument("--feature-filter", type=float, default=None, metavar="ALPHA",
                   help=f"servo only: α of the feature filter (as `run --feature-filter`; 0 = off; default {FEATURE_FILTER_ALPHA} for tracked "
                        "corners on six DOF)")
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
                   help="sequence seeds (track; default 100 101 102, natural 500 501) or episode seeds (servo)")
    p.add_argument("--episodes", type=int, default=None,
                   help="servo only: episodes per scenario and tracker, seeds 200, 201, … (default 20)")
    p.add_argument("--camera", default=None, choices=SENSOR_NAMES,
                   help=f"camera model of every sequence/episode (default {REALISTIC_PRESET}; ideal = clean renders)")
    p.add_argument("--people", default=None, choices=PEOPLE_STYLES,
                   help="sim imagery: how the people look (default textured; plain = the flat figures of earlier "
                        "benchmarks)")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("sweep", formatter_class=HelpFormatter,
                       help="parameter sweeps from a TOML spec, on a local pool or Ray; resumable (hvs_sim/sweep.py)")
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

    p = sub.add_parser("budget", formatter_class=HelpFormatter,
                       help="what accuracy 6-DOF servoing can reach: the Cramér–Rao bound on the camera's pose at the "
                            "goal for a camera, a target and a standoff (hvs_sim/bench/budget.py)")
    p.add_argument("--camera", nargs="+", default=["phone_handheld"], choices=SENSOR_NAMES, metavar="NAME",
                   help=f"camera presets: {', '.join(SENSOR_NAMES)} (default phone_handheld)")
    p.add_argument("--target", default=None, help="a flag or natural texture name (default: the scenes' star_field)")
    p.add_argument("--target-image", default=None, help="any PNG/JPEG file as the target")
    p.add_argument("--target-width", type=float, default=None, help="the target's width in metres (default 0.15)")
    p.add_argument("--standoff", type=float, default=0.8, help="the camera's distance to the target at the goal (m)")
    p.add_argument("--out", default="out/budget", help="folder for budget.json, budget.md and budget.png")
    p.add_argument("--overwrite", action="store_true", help="replace earlier results in a non-empty --out")
    p.set_defaults(func=cmd_budget)

    p = sub.add_parser("scenes", formatter_class=HelpFormatter, help="list scenario presets, camera presets, wall sets and targets")
    p.add_argument("--list", action="store_true", help="list them (the default)")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser("demo", formatter_class=HelpFormatter, help="the README's demo on built-in defaults (headless, offline)")
    p.add_argument("--out", default="out/demo", help="folder for run.json, run.rrd and the figures")
    p.set_defaults(func=cmd_demo)

    from hvs_sim.video import add_track_parser  # here, not at the top: it loads OpenCV and the trackers
    add_track_parser(sub)
    return parser


EXIT_SIGINT, EXIT_SIGTERM = 130, 143  # the shell's codes for a process ended by those signals
EXIT_OUTPUT_FAILED = 1  # the run completed but an output it was asked for could not be written


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the process is so that the clean-up written for Ctrl-C runs for it too:
    partial summaries marked interrupted, recordings closed, benchmark workers ended."""


_SIGTERM_SEEN = []  # set by the handler: a command may catch the interrupt itself and return 130


def _on_sigterm(signum, frame):
    _SIGTERM_SEEN.append(signum)
    raise Terminated()


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
    try:
        code = args.func(args)
    except HvsError as exc:
        print(f"hvs-sim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"hvs-sim: {'terminated (SIGTERM)' if _SIGTERM_SEEN else 'interrupted (Ctrl-C)'}: stopped; what was "
              "finished is kept, and summaries written so far say interrupted", file=sys.stderr)
        code = EXIT_SIGINT
    finally:
        if handle:
            signal.signal(signal.SIGTERM, previous)
    return EXIT_SIGTERM if _SIGTERM_SEEN and code == EXIT_SIGINT else code


if __name__ == "__main__":
    sys.exit(main())
