"""`hvs-sim scene` (a scenario rendered open-loop to frames and ground truth) and `hvs-sim scenes` (what a scene
can be built from)."""

from __future__ import annotations

import json
from pathlib import Path

from hvs_sim.cli.common import HelpFormatter, _add_scene_args, _scenario_from_args
from hvs_sim.errors import ConfigError
from hvs_sim.outputs import fresh_out_dir, write_image

SCENE_OUTPUTS = ("frames.mp4", "frames/*.png", "ground_truth.csv", "ground_truth.npz", "scenario.json", "preview.png")
MAX_SCENE_FRAMES = 36_000  # 20 minutes at 30 fps: --frames above it is refused (a typo, or a disk filled for hours)


def cmd_scene(args) -> int:
    import cv2
    import numpy as np

    from hvs_sim.render.sequence import iterate_sequence

    if args.frames is not None and not 1 <= args.frames <= MAX_SCENE_FRAMES:
        raise ConfigError(f"--frames must be from 1 to {MAX_SCENE_FRAMES} ({MAX_SCENE_FRAMES // 1800} minutes at 30 "
                          f"fps), got {args.frames}")
    scenario = _scenario_from_args(args)
    inputs = _check_scene_outputs(args, scenario.n_frames if args.frames is None else args.frames)
    if args.target_image:  # a damaged image is refused before --out is made
        from hvs_sim.scene.images import load_image

        load_image(args.target_image, "target image")
    out = fresh_out_dir(args.out, args.overwrite, SCENE_OUTPUTS, inputs=inputs)
    meta = _write(scenario, out, args)
    # a preview: the first frame with the ground-truth outline and centre
    frame, gt = next(iterate_sequence(scenario, 1))
    bgr = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
    cv2.polylines(bgr, [np.round(gt.corners * 16).astype(np.int32)], True, (0, 255, 0), 1, cv2.LINE_AA, shift=4)
    cv2.drawMarker(bgr, tuple(np.round(gt.center).astype(int)), (0, 255, 0), cv2.MARKER_CROSS, 12, 1)
    write_image(out / "preview.png", bgr)
    print(json.dumps({"out": str(out), "frames": meta["frames"], "peak_occlusion": round(meta["peak_occlusion"], 3)}))
    return 0


def _check_scene_outputs(args, frames: int) -> list[str]:
    """Every file scene writes, checked before the render: none is an input or in an input folder (--target-image,
    --wall-images), none is written through a link, and --mcap is a new folder outside --out's files. Returns the
    inputs, which --overwrite never removes."""
    from hvs_sim.outputs import check_apart, check_replaceable

    inputs = [p for p in (args.target_image, args.wall_images) if p]
    out = Path(args.out)
    if str(args.out).strip() == "":
        raise ConfigError("--out is empty; give a folder (it is created when missing)")
    files = {f"--out's {name}": out / name for name in ("scenario.json", "ground_truth.csv", "ground_truth.npz",
                                                          "preview.png")}
    if args.format == "mp4":
        files["--out's frames.mp4"] = out / "frames.mp4"
    else:
        files.update({f"--out's frames/{i:05d}.png": out / "frames" / f"{i:05d}.png" for i in (0, frames - 1)})
    if args.mcap:
        if Path(args.mcap).exists() or Path(args.mcap).is_symlink():
            raise ConfigError(f"--mcap {args.mcap} exists: a ROS 2 bag is a new folder; give a path that does not exist")
        files["--mcap"] = Path(args.mcap)
    check_apart(inputs, files)
    check_replaceable(files, overwrite=True, root=out)  # a link among them is refused; --overwrite is checked later
    return inputs


def _write(scenario, out: Path, args) -> dict:
    """The sequence, and with --mcap its ROS 2 bag, written under a temporary name and renamed into place when whole."""
    from hvs_sim.render.sequence import write_sequence

    if not args.mcap:
        return write_sequence(scenario, out, fmt=args.format, n_frames=args.frames)
    from hvs_sim.outputs import settle, temporary_beside
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.viz.rosbag import SceneBag

    final = Path(args.mcap)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_beside(final)
    cam = scenario.camera
    bag = SceneBag(tmp, Renderer.intrinsics_of(scenario), cam.width, cam.height, cam.sensor.distortion, final.name)
    done = False
    try:
        meta = write_sequence(scenario, out, fmt=args.format, n_frames=args.frames, on_frame=bag.log,
                              on_start=bag.start)
        bag.close()
        done = True
    finally:
        settle(tmp, final, keep=done)
    print(f"ROS 2 bag: {final} ({', '.join(f'{t} {n}' for t, n in bag.count.items())})")
    return meta


def cmd_scenes(args) -> int:
    """List what a scene can be built from: scenario presets, camera presets, wall sets, targets."""
    from hvs_sim.scene.flag_art import FLAG_NAMES
    from hvs_sim.scene.scenarios import SCENARIO_NAMES, WALL_SETS, make_scenario
    from hvs_sim.scene.textures import NATURAL_TEXTURES, TEXTURE_SETS
    from hvs_sim.sensor import SENSOR_PRESETS

    print("scenarios (--scenario):")
    for name in SCENARIO_NAMES:
        sc = make_scenario(name)
        people = ", ".join(f"{o.kind} at {o.t_cross:g} s" for o in sc.occluders) or "nobody"
        print(f"  {name:16s} {sc.duration:4.1f} s  target {sc.target_label:14s} wall {sc.wall:12s} people: {people}")
    print("camera presets (--camera):")
    for name, m in SENSOR_PRESETS.items():
        print(f"  {name:16s} " + ("clean renders, every effect off" if m.is_ideal else
              f"exposure {m.exposure_ms:g} ms, {m.white_e:g} e- from white, read noise {m.read_noise_e:g} e-, "
              f"AE target {m.ae_target:g}, JPEG {f'q{m.jpeg_quality}' if m.jpeg_quality else 'off'}, light dim {m.light_dim:g} / flicker {m.light_flicker:g}"
              + (f", distortion k1 {m.distortion[0]:g}" if m.distortion else "")))
    from hvs_sim.scene.arms import ARM_NAMES, arm_summary

    print("arms (--arm, with the camera on the arm):")
    for name in ARM_NAMES:
        try:
            a = arm_summary(name)
        except ConfigError as exc:  # robosuite's model files missing: say how to get them
            print(f"  {name:16s} not available: {exc}")
            continue
        limits = " ".join("free" if lim is None else f"{lim[0]:.0f}…{lim[1]:.0f}" for lim in a["joint_limits_deg"])
        speeds = " ".join(f"{v:.0f}" for v in a["speed_limits_deg_s"])
        print(f"  {name:16s} {a['label']}, reach {a['reach_m']:.3f} m, joint limits (°) {limits}; speed limits (°/s) "
              f"{speeds}; model: {a['source']}")
    print("wall sets (--wall): " + ", ".join(WALL_SETS))
    for name, members in TEXTURE_SETS.items():
        print(f"  {name:16s} {', '.join(members)}")
    print("targets (--target): flags " + ", ".join(FLAG_NAMES))
    print("                    natural textures " + ", ".join(NATURAL_TEXTURES))
    print("                    or any image file: --target-image PATH [--target-width M]")
    return 0


def add_scene_parser(sub) -> None:
    p = sub.add_parser("scene", formatter_class=HelpFormatter, help="render a scenario open-loop to frames + ground truth")
    _add_scene_args(p, mount=True)
    p.add_argument("--out", default="out/scene", help="output folder")
    p.add_argument("--format", choices=("mp4", "png"), default="mp4", help="frames as one video or one PNG each")
    p.add_argument("--frames", type=int, default=None, help="number of frames (default: the scenario's duration)")
    p.add_argument("--shadows", action="store_true", help="cast shadows (about 5x slower on a CPU)")
    p.add_argument("--mcap", default=None, metavar="DIR",
                   help="also write a ROS 2 bag (MCAP) of the frames and their truth: a new folder (hvs_sim/viz/rosbag.py)")
    p.add_argument("--overwrite", action="store_true", help="replace earlier results in a non-empty --out")
    p.set_defaults(func=cmd_scene)


def add_scenes_parser(sub) -> None:
    p = sub.add_parser("scenes", formatter_class=HelpFormatter, help="list scenario presets, camera presets, wall sets and targets")
    p.add_argument("--list", action="store_true", help="list them (the default)")
    p.set_defaults(func=cmd_scenes)
