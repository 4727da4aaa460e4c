"""What the `hvs-sim` commands share: the scene options and the scenario they build (run, scene; budget reads the
target options), provenance, the help formatter, the bench options given, and the exit codes and SIGTERM
handling of `main`."""

from __future__ import annotations

import argparse

from hvs_sim.errors import ConfigError


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


def camera_model(preset: str, blur: str | None):
    """A preset's name, or its SensorModel with its motion blur made another way (`--blur`)."""
    from hvs_sim.sensor import sensor_preset

    if blur is None:
        return preset
    if sensor_preset(preset).exposure_ms <= 0:
        raise ConfigError(f"--blur {blur}: camera {preset!r} has no exposure time, so no motion blur to make; give a "
                          "camera with one (webcam, phone_handheld, robot_cell, low_light)")
    return sensor_preset(preset, blur=blur)


def _scenario_from_args(args):
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    overrides = {"camera": CameraConfig(width=args.width, height=args.height, fovy=args.fovy,
                                        sensor=camera_model(args.camera, getattr(args, "blur", None)),
                                        multisample=args.multisample, supersample=args.supersample),
                 **_target_overrides(args)}
    if args.wall_images and not args.wall:
        overrides["wall"] = "flags"  # the folder replaces the preset's wall set
    for key in ("wall", "wall_images", "people"):
        if getattr(args, key) is not None:
            overrides[key] = getattr(args, key)
    if getattr(args, "shadows", False):
        overrides["shadows"] = True
    mount = getattr(args, "mount", "arm")
    if args.arm is not None:
        if mount != "arm":
            raise ConfigError(f"--arm {args.arm} puts the camera on an arm: add --mount arm")
        overrides["arm"] = args.arm
    return make_scenario(args.scenario, mount=mount, seed=args.seed, **overrides)


def _add_scene_args(p: argparse.ArgumentParser, mount: bool) -> None:
    from hvs_sim.scene.scenarios import (
        DEFAULT_MULTISAMPLE,
        DEFAULT_SUPERSAMPLE,
        MULTISAMPLE_CHOICES,
        PEOPLE_STYLES,
        SCENARIO_NAMES,
        SUPERSAMPLE_CHOICES,
        WALL_SETS,
    )
    from hvs_sim.sensor import SENSOR_NAMES

    p.add_argument("--scenario", default="walk_by", help=f"one of: {', '.join(SCENARIO_NAMES)} (hvs-sim scenes --list)")
    if mount:  # `run` is closed-loop: its camera is on the arm, so it offers no --mount
        p.add_argument("--mount", default="handheld", choices=("handheld", "arm"), help="where the camera is")
    p.add_argument("--seed", type=int, default=0, help="seeds the person, the shake, the sensor noise")
    from hvs_sim.scene.arms import ARM_NAMES, DEFAULT_ARM

    p.add_argument("--arm", default=None, choices=ARM_NAMES,
                   help=f"the arm the camera rides on (default {DEFAULT_ARM}; hvs-sim scenes --list shows each)")
    p.add_argument("--camera", default="ideal", choices=SENSOR_NAMES,
                   help="camera model: exposure, blur, noise, JPEG, distortion (default: ideal = clean renders)")
    add_blur_argument(p)
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
    p.add_argument("--supersample", type=int, default=DEFAULT_SUPERSAMPLE, choices=SUPERSAMPLE_CHOICES,
                   help="each pixel the mean of k×k samples of the scene, as a sensor's pixel integrates light over "
                        "its area (1 = off; 2 costs 2–4× a frame's render; docs/results.md)")


def _provenance(argv: list[str]) -> dict:
    """The command line beside the code it ran (hvs_sim.provenance)."""
    from hvs_sim.provenance import code_provenance

    return {"command": "hvs-sim " + " ".join(argv), **code_provenance()}


def finish_provenance(started: dict) -> dict:
    """`started` (_provenance at a run's start) with the code at its end: `moved` when the commit or the package's
    uncommitted changes differ, so a run whose tree moved under it is never cited as one commit's result."""
    from hvs_sim.provenance import code_provenance, moved

    end = code_provenance()
    return {**started, "commit_end": end["commit"], "code_modified_end": end["code_modified"],
            "moved": moved(started, end)}


def _given(args, *names) -> dict:
    """The bench options the user gave, as config fields (tuples)."""
    return {field: tuple(getattr(args, opt)) for opt, field in names if getattr(args, opt)}


class HelpFormatter(argparse.HelpFormatter):
    """Every option's help shows its default, unless the help already says it."""

    def _get_help_string(self, action):
        text = action.help or ""
        d = action.default
        if "default" not in text and d is not None and d is not False and d != argparse.SUPPRESS and action.option_strings:
            text += " (default: %(default)s)"
        return text


EXIT_SIGINT, EXIT_SIGTERM = 130, 143  # the shell's codes for a process ended by those signals
EXIT_OUTPUT_FAILED = 1  # the run completed but an output it was asked for could not be written


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the process is so that the clean-up written for Ctrl-C runs for it too:
    partial summaries marked interrupted, recordings closed, benchmark workers ended."""


_SIGTERM_SEEN = []  # set by the handler: a command may catch the interrupt itself and return 130


def stop_reason() -> str:
    """How the user stopped the command, for its message: SIGTERM is named as SIGTERM, not as a Ctrl-C."""
    return "terminated (SIGTERM)" if _SIGTERM_SEEN else "interrupted (Ctrl-C)"


def _on_sigterm(signum, frame):
    _SIGTERM_SEEN.append(signum)
    raise Terminated()


def add_blur_argument(p) -> None:
    from hvs_sim.sensor import BLUR_MODES

    p.add_argument("--blur", default=None, choices=BLUR_MODES,
                   help="how the camera's motion blur is made: subframes (default: a render per sub-frame of the "
                        "exposure) or field (one render blurred along each pixel's motion; docs/results.md)")
