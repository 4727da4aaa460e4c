"""The env's expert: the IBVS law v = −λ L⁺ e on the "features" observation, as a policy that answers the env's
normalised action. A baseline to compare a learned policy with, and the teacher of the offline datasets
(hvs_sim.bench.dataset): what the closed loop does with ground-truth corners, in the env's units."""

from __future__ import annotations

import numpy as np

from hvs_sim.control.laws.ibvs import DOF_NAMES, IBVSConfig, IBVSController
from hvs_sim.errors import ConfigError


class IBVSExpert:
    """obs, info → action: six-DOF IBVS on the observed corners, its twist bounded by the env's max_linear and
    max_angular and divided by them (the action space is [−1, 1]⁶). Desired depth: the scenario's standoff; depth of
    the current corners from their apparent size, as the loop's default."""

    def __init__(self, env, gain: float = IBVSConfig.gain, truth: bool = False):
        """truth: read the target's true corners and s* from the env instead of the observation, with any obs_mode
        (the teacher of image datasets); otherwise the env must give the 'features' observation."""
        env = env.unwrapped
        if (env.obs_mode != "features" and not truth) or env.action_type != "twist":
            raise ConfigError(f"the IBVS expert reads the 'features' observation (or the truth, truth=True) and answers "
                              f"a twist: build the env with obs_mode='features' and action_type='twist' (got "
                              f"{env.obs_mode!r}, {env.action_type!r})")
        self.truth = truth
        self.env, self.scale = env, np.asarray(env.scale, float)
        self.config = IBVSConfig(gain=gain, dofs=DOF_NAMES, max_linear=float(self.scale[0]),
                                 max_angular=float(self.scale[3]))
        self._law: IBVSController | None = None
        self._key: tuple | None = None

    def __call__(self, obs: dict, info: dict) -> np.ndarray:
        if self.truth:
            corners = self.env.task.truth(occlusion=False).corners  # the task's truth, as the env grades
            obs = {"features": corners.astype(np.float64), "desired": self.env.desired}
        key = (np.asarray(obs["desired"]).tobytes(), np.asarray(info["K"]).tobytes())
        if key != self._key:  # a new episode (or camera): s* and K change only at a reset
            self._law = IBVSController(info["K"], obs["desired"], self.env.task.scenario.standoff, self.config,
                                       dofs=DOF_NAMES)
            self._key = key
        twist = self._law.compute(obs["features"]).twist
        return np.clip(twist / self.scale, -1.0, 1.0).astype(np.float32)
