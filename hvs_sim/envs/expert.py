"""The env's expert: the IBVS law v = −λ L⁺ e on the "features" observation, as a policy that answers the env's
normalised action. A baseline to compare a learned policy with, and the teacher of the offline datasets
(hvs_sim.bench.dataset): what the closed loop does with ground-truth corners, in the env's units."""

from __future__ import annotations

import numpy as np

from hvs_sim.control.ibvs import DOF_NAMES, IBVSConfig, IBVSController
from hvs_sim.errors import ConfigError


class IBVSExpert:
    """obs, info → action: six-DOF IBVS on the observed corners, its twist bounded by the env's max_linear and
    max_angular and divided by them (the action space is [−1, 1]⁶). Desired depth: the scenario's standoff; depth of
    the current corners from their apparent size, as the loop's default."""

    def __init__(self, env, gain: float = IBVSConfig.gain):
        env = env.unwrapped
        if env.obs_mode != "features" or env.action_type != "twist":
            raise ConfigError(f"the IBVS expert reads the 'features' observation and answers a twist: build the env "
                              f"with obs_mode='features' and action_type='twist' (got {env.obs_mode!r}, "
                              f"{env.action_type!r})")
        self.env, self.scale = env, np.asarray(env.scale, float)
        self.config = IBVSConfig(gain=gain, dofs=DOF_NAMES, max_linear=float(self.scale[0]),
                                 max_angular=float(self.scale[3]))
        self._law: IBVSController | None = None
        self._key: tuple | None = None

    def __call__(self, obs: dict, info: dict) -> np.ndarray:
        key = (np.asarray(obs["desired"]).tobytes(), np.asarray(info["K"]).tobytes())
        if key != self._key:  # a new episode (or camera): s* and K change only at a reset
            self._law = IBVSController(info["K"], obs["desired"], self.env.scene.scenario.standoff, self.config,
                                       dofs=DOF_NAMES)
            self._key = key
        twist = self._law.compute(obs["features"]).twist
        return np.clip(twist / self.scale, -1.0, 1.0).astype(np.float32)
