"""`hvs-sim dataset`: the IBVS expert's episodes in the gym env, written with Minari and read back by Minari."""

import os

import numpy as np
import pytest

from hvs_sim.bench import dataset as ds
from hvs_sim.bench.dataset import DatasetConfig, record
from hvs_sim.errors import ConfigError


@pytest.fixture
def minari_root(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "root"))
    return tmp_path / "root"


def test_the_dataset_is_read_back_by_minari_with_the_expert_converging(minari_root):
    import minari

    summary = record(DatasetConfig(episodes=2, seed=3), minari_root, progress=False)
    assert summary["episodes"] == 2 and summary["success_rate"] == 1.0
    data = minari.load_dataset(ds.DATASET_ID)
    assert data.total_episodes == 2 and data.total_steps == summary["steps"]
    for ep in data.iterate_episodes():
        n = len(ep.actions)
        assert set(ep.observations) == {"features", "desired", "joints"}
        assert ep.observations["features"].shape == (n + 1, 4, 2) and ep.observations["joints"].shape == (n + 1, 18)
        assert np.all(np.abs(ep.actions) <= 1.0) and np.isfinite(ep.actions).all()
        assert ep.terminations[-1] and not ep.terminations[:-1].any() and not ep.truncations.any()
        # the reward is minus the mean corner error, which the expert drives under the env's converge_px
        err = np.linalg.norm(ep.observations["features"] - ep.observations["desired"], axis=2).mean(axis=1)
        assert ep.rewards == pytest.approx(-err[1:], rel=1e-9) and err[-1] < 1.0 < err[0]
    env = data.recover_environment()
    assert env.unwrapped.obs_mode == "features" and env.spec.max_episode_steps == DatasetConfig().max_steps
    with pytest.raises(ConfigError, match="exists"):
        record(DatasetConfig(episodes=1), minari_root, progress=False)


def test_an_interrupted_recording_keeps_the_finished_episodes(minari_root, monkeypatch):
    import minari

    from hvs_sim.envs.expert import IBVSExpert

    real = IBVSExpert.__call__
    seen = {"episode": 0, "frame": -1}

    def interrupted(self, obs, info):  # Ctrl-C three frames into the second episode
        frame = self.env.scene.frame_index
        seen["episode"] += frame < seen["frame"]
        seen["frame"] = frame
        if seen["episode"] == 1 and frame == 3:
            raise KeyboardInterrupt
        return real(self, obs, info)

    monkeypatch.setattr(IBVSExpert, "__call__", interrupted)
    with pytest.raises(KeyboardInterrupt) as caught:
        record(DatasetConfig(episodes=3), minari_root, progress=False)
    assert caught.value.args[0]["episodes"] == 1 and caught.value.args[0]["interrupted"]
    assert minari.load_dataset(ds.DATASET_ID).total_episodes == 1
    assert not [p for p in os.listdir(minari_root) if p.startswith(".")]  # no temporary left


def test_bad_dataset_settings_are_refused():
    for kwargs, words in (({"episodes": 0}, "episodes"), ({"obs_mode": "depth"}, "observation"),
                          ({"dataset_id": "servo"}, "namespace/name-vN"), ({"dataset_id": "../x-v0"}, "namespace")):
        with pytest.raises(ConfigError, match=words):
            DatasetConfig(**kwargs)
