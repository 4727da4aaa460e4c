"""Dev and test seeds of every benchmark, and fresh seeds on demand.

Tuning (experiments/, docs/tuning.md) may look at dev seeds; published figures come from test seeds, which nothing is
tuned on, with a fresh draw beside them (`--fresh N`: seeds from the operating system's entropy, recorded in the
summary) so a reader sees whether the two agree. The splits are disjoint within a benchmark, and their ranges are far
apart so that one added seed never crosses into the other split.

The dev ranges hold every seed the project's tuning ever used: the servo benchmark's 200–219 were its published seeds
until they turned out to have been tuned on (docs/tuning.md), so they are dev seeds now and the test seeds start at
1000; likewise the tracking benchmark's 100–129 and the natural imagery's 500–501.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass

from hvs_sim.errors import ConfigError, choice_error

SPLIT_NAMES = ("dev", "test")
DEFAULT_SPLIT = "test"  # what a benchmark runs when no seeds are named: the figures a reader can trust
FRESH_LOW, FRESH_HIGH = 10_000, 2**31 - 1  # fresh seeds lie above every declared range
MAX_FRESH = 1000


@dataclass(frozen=True)
class Split:
    """A benchmark's seeds: `dev` for tuning, `test` for published figures (disjoint ranges, first seeds first)."""

    dev: range
    test: range

    def __post_init__(self):
        if set(self.dev) & set(self.test):
            raise ValueError("dev and test seeds overlap")  # a programming error in the table below

    def seeds(self, split: str, n: int) -> tuple[int, ...]:
        """The first `n` seeds of `split`."""
        if split not in SPLIT_NAMES:
            raise choice_error("split", split, SPLIT_NAMES)
        pool = self.dev if split == "dev" else self.test
        if n > len(pool):
            raise ConfigError(f"the {split} split has {len(pool)} seeds ({pool.start}–{pool.stop - 1}); asked for {n}")
        return tuple(pool[:n])

    def describe(self) -> str:
        return f"dev {self.dev.start}–{self.dev.stop - 1}, test {self.test.start}–{self.test.stop - 1}"


# benchmark -> its split; "servo" episodes, "track" rendered sequences, "natural" natural-imagery sequences
BENCH_SPLITS: dict[str, Split] = {
    "servo": Split(dev=range(200, 400), test=range(1000, 1200)),
    "track": Split(dev=range(100, 200), test=range(2000, 2200)),
    "natural": Split(dev=range(500, 600), test=range(3000, 3200)),
}
# seeds a default run takes from its split
DEFAULT_COUNT = {"servo": 20, "track": 3, "natural": 2}


def split_of(bench: str) -> Split:
    if bench not in BENCH_SPLITS:
        raise choice_error("benchmark", bench, tuple(BENCH_SPLITS))
    return BENCH_SPLITS[bench]


def fresh_seeds(n: int) -> tuple[int, ...]:
    """`n` distinct seeds from the operating system's entropy, above every declared split (so never a tuned one)."""
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_FRESH:
        raise ConfigError(f"--fresh takes a number of seeds from 1 to {MAX_FRESH}; got {n!r}")
    rng = secrets.SystemRandom()
    seeds: set[int] = set()
    while len(seeds) < n:
        seeds.add(rng.randrange(FRESH_LOW, FRESH_HIGH))
    return tuple(sorted(seeds))


def seed_origin(bench: str, seeds, fresh: bool = False) -> str:
    """What a run's seeds are: "fresh", "test" or "dev" when all lie in that split, else "custom"."""
    if fresh:
        return "fresh"
    split = split_of(bench)
    seeds = set(seeds)
    for name, pool in (("test", split.test), ("dev", split.dev)):
        if seeds and seeds <= set(pool):
            return name
    return "custom"


def check_tuning_seeds(bench: str, seeds, allow_test: bool = False) -> None:
    """Tuning scripts call this on their seeds: a test seed is refused unless the script was told
    `--allow-test-seeds` (and then its output records that it was)."""
    test = sorted(set(seeds) & set(split_of(bench).test))
    if test and not allow_test:
        shown = ", ".join(map(str, test[:5])) + (", …" if len(test) > 5 else "")
        raise ConfigError(f"seeds {shown} are {bench} test seeds ({split_of(bench).describe()}): tuning uses dev seeds; "
                          "pass --allow-test-seeds to look at test seeds anyway (the output then says so)")

