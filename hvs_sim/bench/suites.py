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

from hvs_sim.errors import ConfigError, choice_error

TILT_MAX_DEG = 15.0  # pitch and yaw bound of the 6-DOF start poses (the 4-DOF ones draw none)


@dataclass(frozen=True)
class Suite:
    name: str  # NAME-vN (quick has no version: it is a look, not a result)
    kind: str  # "servo" | "track"
    description: str
    scenarios: tuple[str, ...]
    # episode (servo) or sequence (track) seeds: dev ones tuning may look at, test ones published figures use
    # (disjoint; bench/splits.py); `bench --suite NAME` runs the test seeds unless told `--split dev`
    dev_seeds: tuple[int, ...]
    test_seeds: tuple[int, ...]
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
    retired: str = ""  # why a suite is no longer cited (it stays runnable, on its dev seeds, for old comparisons)

    def __post_init__(self):
        if set(self.dev_seeds) & set(self.test_seeds):
            raise ValueError(f"suite {self.name}: dev and test seeds overlap")  # a programming error in SUITES

    def seeds(self, split: str) -> tuple[int, ...]:
        """The suite's seeds of `split` ("dev" or "test"); a retired suite has no test seeds left."""
        from hvs_sim.bench.splits import SPLIT_NAMES

        if split not in SPLIT_NAMES:
            raise choice_error("split", split, SPLIT_NAMES)
        seeds = self.dev_seeds if split == "dev" else self.test_seeds
        if not seeds:
            raise ConfigError(f"suite {self.name} is retired ({self.retired}); its seeds are dev seeds now: run it "
                              f"with --split dev to compare with its old results, or use {self.name[:-1]}"
                              f"{int(self.name[-1]) + 1} for figures")
        return seeds


_SERVO_TEST = tuple(range(1000, 1020))  # bench/splits.py: servo test seeds start at 1000
_RETIRED = "its seeds 200-219 were tuned on (docs/tuning.md)"

SUITES: dict[str, Suite] = {s.name: s for s in (
    Suite("quick", "servo", "a look in about two minutes: someone walks by and pauses in front of the target; ground "
          "truth and the homography hybrid beside the methods you name; 4 episodes, 6-DOF starts, clean renders",
          scenarios=("pause",), dev_seeds=(200, 201, 202, 203), test_seeds=_SERVO_TEST[:4],
          methods=("ground_truth", "hybrid:homography"), extra_steps=20, camera="ideal", with_reference=True),
    Suite("occlusion-v2", "servo", "6-DOF servoing under occlusion: clear, walk_by, pause; 20 episodes each from 6-DOF "
          "start poses; phone_handheld camera; the built-in methods",
          scenarios=("clear", "walk_by", "pause"), dev_seeds=tuple(range(200, 220)), test_seeds=_SERVO_TEST,
          methods=("ground_truth", "ground_truth/pbvs", "hybrid:homography", "hybrid:homography/pbvs", "none/dvs")),
    Suite("occlusion-4dof-v2", "servo", "the same occlusions from start poses without pitch and yaw, for methods that "
          "control translation, depth and roll only (box or similarity trackers)",
          scenarios=("clear", "walk_by", "pause"), dev_seeds=tuple(range(200, 220)), test_seeds=_SERVO_TEST,
          start="4dof", methods=("ground_truth", "hybrid", "hybrid:homography")),
    Suite("track-occlusion-v2", "track", "open-loop tracking accuracy on hand-held footage of the sim scenes: clear, "
          "walk_by, pause, partial, two_people; three sequences each",
          scenarios=("clear", "walk_by", "pause", "partial", "two_people"), dev_seeds=(100, 101, 102),
          test_seeds=(2000, 2001, 2002), methods=("hybrid", "deep_lk", "ecc")),
    # v1: the same as v2 on the seeds the project tuned on; kept so that old folders still compare
    Suite("occlusion-v1", "servo", "occlusion-v2 on its dev seeds (retired)", scenarios=("clear", "walk_by", "pause"),
          dev_seeds=tuple(range(200, 220)), test_seeds=(), retired=_RETIRED,
          methods=("ground_truth", "ground_truth/pbvs", "hybrid:homography", "hybrid:homography/pbvs", "none/dvs")),
    Suite("occlusion-4dof-v1", "servo", "occlusion-4dof-v2 on its dev seeds (retired)",
          scenarios=("clear", "walk_by", "pause"), dev_seeds=tuple(range(200, 220)), test_seeds=(), start="4dof",
          retired=_RETIRED, methods=("ground_truth", "hybrid", "hybrid:homography")),
    Suite("track-occlusion-v1", "track", "track-occlusion-v2 on its dev seeds (retired)",
          scenarios=("clear", "walk_by", "pause", "partial", "two_people"), dev_seeds=(100, 101, 102), test_seeds=(),
          retired="its seeds 100-102 were tuned on (docs/tuning.md)", methods=("hybrid", "deep_lk", "ecc")),
)}
SUITE_NAMES = tuple(SUITES)


def get_suite(name: str, kind: str | None = None) -> Suite:
    """The suite by name (of that kind when given); ConfigError listing the accepted ones."""
    names = [n for n, s in SUITES.items() if kind is None or s.kind == kind]
    if name not in names:
        raise choice_error(f"{kind + ' ' if kind else ''}suite", name, names)
    return SUITES[name]


def describe() -> str:
    """`hvs-sim bench suites`: each suite with what it holds, its dev and test seeds."""

    def span(seeds):
        return f"{seeds[0]}–{seeds[-1]} ({len(seeds)})" if seeds else "none (retired)"

    lines = []
    for s in SUITES.values():
        extra = (f"starts {s.start}, {s.extra_steps} steps past the scenario, success ≤ {s.success_px:g} px"
                 if s.kind == "servo" else f"mounts {', '.join(s.mounts)}")
        lines += [f"{s.name} ({s.kind}): {s.description}" + (f"; retired: {s.retired}" if s.retired else ""),
                  f"    scenarios {', '.join(s.scenarios)}; seeds: test {span(s.test_seeds)}, dev {span(s.dev_seeds)}",
                  f"    camera {s.camera} {s.width}×{s.height}, arm {s.arm}; {extra}",
                  f"    reference methods: {', '.join(s.methods)}"
                  + (" (always run beside yours)" if s.with_reference else " (run when you name none)")]
    lines.append("--split test (the default) runs a suite's test seeds, --split dev its dev seeds (what tuning may "
                 "look at), --fresh N N seeds drawn now")
    return "\n".join(lines) + "\n"
