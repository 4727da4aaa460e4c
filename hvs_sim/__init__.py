"""hvs_sim: a MuJoCo simulator of occlusion-robust image-based visual servoing.

Importing the package is cheap: MuJoCo, dm_control and torch load only when their parts are used.
"""

from hvs_sim.errors import ConfigError, HvsError, InputError, RenderError, StateError, WeightsError
from hvs_sim.plugins import register_controller, register_policy, register_tracker

__version__ = "0.1.0"
__all__ = ["ConfigError", "HvsError", "InputError", "RenderError", "StateError", "WeightsError", "__version__",
           "register_controller", "register_policy", "register_tracker"]


def _register_envs() -> None:
    from gymnasium.envs.registration import register, registry

    if "hvs_sim/VisualServo-v0" not in registry:  # v0: joint angles wrapped to [−π, π), as first released
        register(id="hvs_sim/VisualServo-v0", entry_point="hvs_sim.envs.visual_servo:VisualServoEnv",
                 max_episode_steps=300)
    if "hvs_sim/VisualServo-v1" not in registry:  # v1: joints as (sin, cos, velocity)
        register(id="hvs_sim/VisualServo-v1", entry_point="hvs_sim.envs.visual_servo:VisualServoEnv",
                 max_episode_steps=300, kwargs={"joints": "sincos"})


_register_envs()
