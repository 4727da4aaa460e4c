"""hvs_sim: a MuJoCo simulator of occlusion-robust image-based visual servoing.

Importing the package is cheap: MuJoCo, dm_control and torch load only when their parts are used.
"""

from hvs_sim.errors import ConfigError, HvsError, InputError, RenderError, StateError, WeightsError

__version__ = "0.1.0"
__all__ = ["HvsError", "ConfigError", "InputError", "StateError", "RenderError", "WeightsError", "__version__"]
