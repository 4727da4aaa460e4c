"""hvs_sim: a MuJoCo simulator of occlusion-robust image-based visual servoing.

Importing the package is cheap: MuJoCo, dm_control and torch load only when their parts are used. The names in
`__all__` are the ones a user reaches for; apart from the errors, each is imported from its module the first time
it is asked for (module `__getattr__`, PEP 562), so `import hvs_sim` loads none of them.
"""

from __future__ import annotations

import importlib

from hvs_sim.errors import ConfigError, HvsError, InputError, OutputError, RenderError, StateError, WeightsError

__version__ = "0.1.0"

# name -> the module that defines it, imported on first use
_LAZY = {
    "LoopConfig": "hvs_sim.servo.config",
    "ServoLoop": "hvs_sim.servo.loop",
    "ServoTask": "hvs_sim.servo.task",
    "run_episode": "hvs_sim.runner",
    "Scenario": "hvs_sim.scene.scenarios",
    "make_scenario": "hvs_sim.scene.scenarios",
    "SCENARIO_NAMES": "hvs_sim.scene.scenarios",
    "Scene": "hvs_sim.scene.world",
    "Renderer": "hvs_sim.render.renderer",
    "SensorModel": "hvs_sim.sensor",
    "SENSOR_PRESETS": "hvs_sim.sensor",
    "Track": "hvs_sim.tracking",
    "TRACKER_NAMES": "hvs_sim.tracking",
    "make_tracker": "hvs_sim.tracking",
    "IBVSConfig": "hvs_sim.control.laws.ibvs",
    "register_controller": "hvs_sim.plugins",
    "register_policy": "hvs_sim.plugins",
    "register_tracker": "hvs_sim.plugins",
}

__all__ = [  # the errors, __version__ and _LAZY's names (tests/test_layout.py checks they agree)
    "SCENARIO_NAMES",
    "SENSOR_PRESETS",
    "TRACKER_NAMES",
    "ConfigError",
    "HvsError",
    "IBVSConfig",
    "InputError",
    "LoopConfig",
    "OutputError",
    "RenderError",
    "Renderer",
    "Scenario",
    "Scene",
    "SensorModel",
    "ServoLoop",
    "ServoTask",
    "StateError",
    "Track",
    "WeightsError",
    "__version__",
    "make_scenario",
    "make_tracker",
    "register_controller",
    "register_policy",
    "register_tracker",
    "run_episode",
]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'hvs_sim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # the next access is a plain attribute
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


def _register_envs() -> None:
    from gymnasium.envs.registration import register, registry

    if "hvs_sim/VisualServo-v0" not in registry:  # v0: joint angles wrapped to [−π, π), as first released
        register(id="hvs_sim/VisualServo-v0", entry_point="hvs_sim.envs.visual_servo:VisualServoEnv",
                 max_episode_steps=300)
    if "hvs_sim/VisualServo-v1" not in registry:  # v1: joints as (sin, cos, velocity)
        register(id="hvs_sim/VisualServo-v1", entry_point="hvs_sim.envs.visual_servo:VisualServoEnv",
                 max_episode_steps=300, kwargs={"joints": "sincos"})


_register_envs()
