"""Offline-RL datasets: episodes of the gym env driven by the IBVS expert, written in Minari's format.

`hvs-sim dataset --out DIR` rolls the expert (hvs_sim.envs.expert: six-DOF IBVS on the true corners) out in
`hvs_sim/VisualServo-v1` from the servo benchmark's start poses (bench.servo.episode_offset: lateral ±10 cm, depth
0.7–1.4 × the standoff, roll ±60°, pitch and yaw ±15°; a start the arm cannot reach or with the target out of view is
drawn again, as the benchmark does, and counted) and stores observations, actions (the expert's twist in the env's
[−1, 1] units, what the env executed), rewards, terminations and truncations through Minari's buffer API
(`create_dataset_from_buffers`, HDF5). DIR is a Minari datasets root:

    MINARI_DATASETS_PATH=DIR python -c "import minari; print(minari.load_dataset('hvs_sim/servo-expert-v0'))"

`dataset.recover_environment()` rebuilds the env with the recorded settings. Minari is used, not a format of ours, so
that d3rlpy, TorchRL and the other readers of Minari take the data as it is; its JAX-based extras are not needed.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
from pathlib import Path

import numpy as np

from hvs_sim.errors import ConfigError, InputError, OutputError
from hvs_sim.validate import check_number

DATASET_ID = "hvs_sim/servo-expert-v0"  # Minari's namespace/name-version
DATASET_OBS_MODES = ("features", "image", "image+goal")
HDF5_OVERHEAD = 2  # the free space a dataset needs, as a multiple of its arrays' bytes (HDF5's own structures)
START_DRAWS = 20  # candidate start poses per episode, as the servo benchmark's MAX_DRAWS


@dataclasses.dataclass(frozen=True)
class DatasetConfig:
    episodes: int = 50
    seed: int = 0  # episode k uses env seed `seed + k` and the benchmark's start draws of that seed
    scenario: str = "clear"
    camera: str = "ideal"
    obs_mode: str = "features"
    max_steps: int = 300  # an episode not converged by then is truncated
    width: int = 160
    height: int = 120
    dataset_id: str = DATASET_ID

    def __post_init__(self):
        check_number("episodes", self.episodes, 1, 100_000, integer=True)
        check_number("seed", self.seed, 0, integer=True)
        check_number("max_steps", self.max_steps, 1, 100_000, integer=True)
        if self.obs_mode not in DATASET_OBS_MODES:
            raise ConfigError(f"dataset observation {self.obs_mode!r} unknown; accepted: {', '.join(DATASET_OBS_MODES)}")
        parts = self.dataset_id.split("/")
        if (len(parts) != 2 or any(p in ("", ".", "..") for p in parts) or "\\" in self.dataset_id
                or not self.dataset_id.rsplit("-v", 1)[-1].isdigit()):
            raise ConfigError(f"dataset id {self.dataset_id!r} must read namespace/name-vN (e.g. {DATASET_ID})")

    def env_kwargs(self) -> dict:
        return {"scenario": self.scenario, "camera": self.camera, "obs_mode": self.obs_mode, "joints": "sincos",
                "width": self.width, "height": self.height, "max_linear": 0.15, "max_angular": 0.6}


def benchmark_start(env, seed: int) -> tuple[tuple, dict, int]:
    """Reset `env` at the servo benchmark's start pose of `seed`: (obs, info), and the draws it took."""
    from hvs_sim.bench.servo import episode_offset

    last = None
    for draw in range(START_DRAWS):
        offset = episode_offset(seed, env.unwrapped.base.standoff, draw)
        try:
            return env.reset(seed=seed, options={"start_offset": offset}), draw + 1
        except InputError as exc:  # out of reach or out of view: the benchmark draws again
            last = exc
    raise InputError(f"no usable benchmark start pose for seed {seed} in {START_DRAWS} draws ({last})")


def record(config: DatasetConfig, out, progress: bool = True) -> dict:
    """Roll the expert out and write the dataset under `out` (a Minari datasets root, renamed into place when complete;
    on Ctrl-C the finished episodes are written). Returns a summary."""
    import gymnasium as gym
    import minari
    from minari.data_collector import EpisodeBuffer
    from tqdm.auto import tqdm

    import hvs_sim  # noqa: F401 - registers the env

    out = Path(out)
    final = out / config.dataset_id
    if final.exists():
        raise ConfigError(f"{final} exists: give another --out or --dataset-id, or remove it")
    # the passive checker keeps the first reset's data, and a first reset refused (a start out of view) leaves it empty
    env = gym.make("hvs_sim/VisualServo-v1", max_episode_steps=config.max_steps, disable_env_checker=True,
                   **config.env_kwargs())
    from hvs_sim.envs.expert import IBVSExpert

    expert = IBVSExpert(env, truth=config.obs_mode != "features")  # image modes: the teacher reads the truth
    buffers, summary = [], {"episodes": 0, "steps": 0, "converged": 0, "start_draws": [], "interrupted": False}
    try:
        for k in tqdm(range(config.episodes), desc="dataset", unit="episode", disable=not progress):
            seed = config.seed + k
            (obs, info), draws = benchmark_start(env, seed)
            ep = _Episode(obs)
            done = False
            while not done:
                action = expert(obs, info)
                obs, reward, term, trunc, info = env.step(action)
                ep.add(obs, action, reward, term, trunc)
                done = term or trunc
            buffers.append(ep.buffer(EpisodeBuffer, len(buffers), seed))
            summary["episodes"] += 1
            summary["steps"] += len(ep.rewards)
            summary["converged"] += int(bool(info["is_success"]))
            summary["start_draws"].append(draws)
    except KeyboardInterrupt:  # the finished episodes are written; any other error writes nothing
        summary["interrupted"] = True
        if not buffers:
            env.close()
            raise
    except BaseException:
        env.close()
        raise
    try:
        _write(buffers, env, config, out)
    finally:
        env.close()
    summary.update(dataset_id=config.dataset_id, path=str(final), success_rate=summary["converged"] / summary["episodes"],
                   minari_version=minari.__version__, config=dataclasses.asdict(config))
    if summary["interrupted"]:
        raise KeyboardInterrupt(summary)
    return summary


@dataclasses.dataclass
class _Episode:
    first: dict
    observations: list = dataclasses.field(default_factory=list)
    actions: list = dataclasses.field(default_factory=list)
    rewards: list = dataclasses.field(default_factory=list)
    terminations: list = dataclasses.field(default_factory=list)
    truncations: list = dataclasses.field(default_factory=list)

    def add(self, obs, action, reward, term, trunc) -> None:
        self.observations.append(obs)
        self.actions.append(np.asarray(action, np.float32))
        self.rewards.append(float(reward))
        self.terminations.append(bool(term))
        self.truncations.append(bool(trunc))

    def buffer(self, cls, index: int, seed: int):
        """Minari's EpisodeBuffer: observations stacked key by key (one more than the actions: the reset's)."""
        obs = [self.first, *self.observations]
        stacked = {key: np.stack([o[key] for o in obs]) for key in self.first}
        return cls(id=index, seed=seed, observations=stacked, actions=np.stack(self.actions), rewards=self.rewards,
                   terminations=self.terminations, truncations=self.truncations)


def _nbytes(value) -> int:
    """The bytes of the arrays in an episode buffer (dataclass, dict, list), what the HDF5 file will hold."""
    if isinstance(value, np.ndarray):
        return value.nbytes
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = vars(value)
    if isinstance(value, dict):
        return sum(_nbytes(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return sum(_nbytes(v) for v in value)
    return 8 if isinstance(value, (int, float, bool, np.generic)) else 0


def _write(buffers, env, config: DatasetConfig, out: Path) -> None:
    """Minari writes under MINARI_DATASETS_PATH: a temporary root beside `out`, its dataset renamed into place."""
    import tempfile

    import minari

    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".hvs_sim-dataset-", dir=out))
    before = os.environ.get("MINARI_DATASETS_PATH")
    try:
        os.environ["MINARI_DATASETS_PATH"] = str(tmp)
        from hvs_sim import outputs

        # HDF5 crashes (SIGSEGV) on a disk that fills under it: refuse first, with room for its overhead
        outputs.ensure_space(tmp / "data.hdf5", HDF5_OVERHEAD * _nbytes(buffers))
        minari.create_dataset_from_buffers(
            dataset_id=config.dataset_id, buffer=buffers, env=env.spec, eval_env=env.spec, algorithm_name="IBVS expert (hvs_sim)",
            description="hvs_sim's gym env driven by six-DOF IBVS on the true corners from the servo benchmark's start "
                        "poses (hvs_sim.bench.dataset)", code_permalink="https://github.com/hvs-sim/hvs_sim",
            author="hvs_sim", author_email="hvs-sim@users.noreply.github.com", data_format="hdf5")
        final = out / config.dataset_id
        final.parent.mkdir(parents=True, exist_ok=True)
        os.replace(tmp / config.dataset_id, final)
        namespace = config.dataset_id.split("/")[0]
        meta = tmp / namespace / "namespace_metadata.json"
        if meta.exists() and not (out / namespace / meta.name).exists():
            os.replace(meta, out / namespace / meta.name)
    except OSError as exc:
        raise OutputError(f"could not write the dataset under {out}: {exc}") from exc
    finally:
        if before is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = before
        shutil.rmtree(tmp, ignore_errors=True)
