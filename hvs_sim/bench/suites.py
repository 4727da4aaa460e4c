"""Versioned benchmark suites: frozen specs of the servo and tracking benchmarks, as gymnasium versions its envs.

A suite fixes everything that decides a result: scenarios, the start-pose distribution, episode seeds, camera, arm,
image size, step budget and success rules. Anything that changes results gets a new version (`-v2`); old versions
stay here and stay runnable, so two result folders of one suite compare episode by episode (`hvs-sim bench
compare`). A user's own methods are named beside the suite's (`--methods`), never instead of its settings.

Start poses: `6dof` draws lateral ±10 cm, depth 0.7–1.4 × the standoff, roll ±60°, pitch and yaw ±15° (bench/servo.py);
`4dof` the same without pitch and yaw, so that a method whose features observe only translation, depth and roll (a
box or similarity tracker) is judged on what it can correct.
"""

from __future__ import annotations

from dataclasses import dataclass

from hvs_sim.errors import choice_error

TILT_MAX_DEG = 15.0  # pitch and yaw bound of the 6-DOF start poses (the 4-DOF ones draw none)


@dataclass(frozen=True)
class Suite:
    name: str  # NAME-vN (quick has no version: it is a look, not a result)
    kind: str  # "servo" | "track"
    description: str
    scenarios: tuple[str, ...]
    seeds: tuple[int, ...]
    # the reference methods: what runs when no methods are named, and with `with_reference` beside the named ones;
    # otherwise the named methods alone (the suite's committed results hold the reference methods to compare with)
    methods: tuple[str, ...]
    camera: str = "phone_handheld"
    arm: str = "jaco"
    width: int = 640
    height: int = 480
    start: str = "6dof"  # servo: the start-pose distribution (module docstring)
    extra_steps: int = 60  # servo: steps past the scenario's end
    success_px: float = 1.0
    mounts: tuple[str, ...] = ("handheld",)  # track
    with_reference: bool = False


SUITES: dict[str, Suite] = {s.name: s for s in (
    Suite("quick", "servo", "a look in about two minutes: someone walks by and pauses in front of the target; ground "
          "truth and the homography hybrid beside the methods you name; 4 episodes, 6-DOF starts, clean renders",
          scenarios=("pause",), seeds=(200, 201, 202, 203), methods=("ground_truth", "hybrid:homography"),
          extra_steps=20, camera="ideal", with_reference=True),
    Suite("occlusion-v1", "servo", "6-DOF servoing under occlusion: clear, walk_by, pause; 20 episodes each from 6-DOF "
          "start poses; phone_handheld camera; the built-in methods",
          scenarios=("clear", "walk_by", "pause"), seeds=tuple(range(200, 220)),
          methods=("ground_truth", "ground_truth/pbvs", "hybrid:homography", "hybrid:homography/pbvs", "none/dvs")),
    Suite("occlusion-4dof-v1", "servo", "the same occlusions from start poses without pitch and yaw, for methods that "
          "control translation, depth and roll only (box or similarity trackers)",
          scenarios=("clear", "walk_by", "pause"), seeds=tuple(range(200, 220)), start="4dof",
          methods=("ground_truth", "hybrid", "hybrid:homography")),
    Suite("track-occlusion-v1", "track", "open-loop tracking accuracy on hand-held footage of the sim scenes: clear, "
          "walk_by, pause, partial, two_people; three sequences each",
          scenarios=("clear", "walk_by", "pause", "partial", "two_people"), seeds=(100, 101, 102),
          methods=("hybrid", "deep_lk", "ecc")),
)}
SUITE_NAMES = tuple(SUITES)


def get_suite(name: str, kind: str | None = None) -> Suite:
    """The suite by name (of that kind when given); ConfigError listing the accepted ones."""
    names = [n for n, s in SUITES.items() if kind is None or s.kind == kind]
    if name not in names:
        raise choice_error(f"{kind + ' ' if kind else ''}suite", name, names)
    return SUITES[name]


def describe() -> str:
    """`hvs-sim bench suites`: each suite with what it holds."""
    lines = []
    for s in SUITES.values():
        size = f"{len(s.scenarios)} scenario(s) × {len(s.seeds)} seed(s)"
        extra = (f"starts {s.start}, {s.extra_steps} steps past the scenario, success ≤ {s.success_px:g} px"
                 if s.kind == "servo" else f"mounts {', '.join(s.mounts)}")
        lines += [f"{s.name} ({s.kind}): {s.description}",
                  f"    scenarios {', '.join(s.scenarios)}; seeds {s.seeds[0]}–{s.seeds[-1]}; {size}",
                  f"    camera {s.camera} {s.width}×{s.height}, arm {s.arm}; {extra}",
                  f"    reference methods: {', '.join(s.methods)}"
                  + (" (always run beside yours)" if s.with_reference else " (run when you name none)")]
    return "\n".join(lines) + "\n"
