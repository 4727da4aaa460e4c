"""The servo laws as the loop drives them (`ServoLaw`): each declares what it uses (`LawCaps`) and is built on each
template's s* into one shape, compute(ControlInput) -> ControlOutput, so that the loop and its plan ask capabilities instead of checking
law names. The built-ins' capabilities are a table here; an outside law (hvs_sim.plugins) declares `uses_features` and
answers (twist, dofs), which `OutsideLaw` bounds as the built-ins bound their own."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hvs_sim.control.laws.ibvs import DOF_NAMES, ControlOutput, IBVSConfig, IBVSController, Law, bound_twist
from hvs_sim.control.laws.pbvs import PBVSController
from hvs_sim.control.protocol import ControlInput
from hvs_sim.errors import ConfigError


@dataclass(frozen=True)
class LawCaps:
    """What a servo law uses, as the loop and its plan ask it."""

    features: bool  # reads the tracked features (False: only the frame and the goal image; no tracker then)
    images: bool  # is given the frame and the goal image (a copy per step: only for those that read them)
    damped: bool  # a least-squares law on the features' L: tracked corners on six DOF are damped (TRACKED_6DOF_DAMPING)
    outside: bool = False  # outside code: any exception it raises is a fault (the built-ins raise HvsError)


def _ibvs(K, desired_px, desired_depth, config, dofs, goal, roi):
    return IBVSController(K, desired_px, desired_depth, config, dofs)


def _pbvs(K, desired_px, desired_depth, config, dofs, goal, roi):
    return PBVSController(K, desired_px, desired_depth, config, dofs)


def _dvs(K, desired_px, desired_depth, config, dofs, goal, roi):
    from hvs_sim.control.laws.dvs import DVSController  # OpenCV's photometric parts load only for it

    return DVSController(K, goal, roi, desired_depth, config)


# the built-in laws (control.laws.ibvs.CONTROLLERS): what each uses, and how it is built on a template
BUILT_IN = {"ibvs": (LawCaps(features=True, images=False, damped=True), _ibvs),
            "pbvs": (LawCaps(features=True, images=False, damped=True), _pbvs),
            "dvs": (LawCaps(features=False, images=True, damped=False), _dvs)}


def law_caps(controller: str, outside=None) -> LawCaps | None:
    """A built-in's capabilities, or an outside law's as it declares them (None: an outside law not built yet, whose
    capabilities are not known)."""
    if controller in BUILT_IN:
        return BUILT_IN[controller][0]
    if outside is None:
        return None
    uses_features = bool(outside.uses_features)
    return LawCaps(features=uses_features, images=True, damped=False, outside=True)  # outside code may read the images


def bounded(twist: np.ndarray, dofs: tuple[str, ...], config: IBVSConfig) -> ControlOutput:
    """An outside law's or policy's twist in the DOFs it commands, under the loop's per-axis bounds (reported as
    saturated when they cut it, as for the built-in laws)."""
    cols = [DOF_NAMES.index(d) for d in dofs]
    out = np.zeros(6)
    out[cols] = np.asarray(twist, float)[cols]
    out, saturated = bound_twist(out, config.max_linear, config.max_angular)
    return ControlOutput(out, np.zeros(0), 0.0, 0.0, saturated, np.zeros(0), tuple(dofs))  # no gain of ours


class OutsideLaw:
    """An outside law (plugins' ExternalController, answering (twist, dofs)) as a ControlOutput, bounded."""

    def __init__(self, law, config: IBVSConfig, dofs: tuple[str, ...]):
        self.law, self.config, self.dofs = law, config, dofs

    def compute(self, inp: ControlInput) -> ControlOutput:
        twist, dofs = self.law.compute(inp)
        return bounded(twist, dofs or self.dofs, self.config)


class ServoLaw:
    """The loop's law: its capabilities, and a fresh law on each template's s* (step 0, the near-goal switch)."""

    def __init__(self, controller: str, outside=None):
        """outside: the built outside law, when `controller` names one (plugins.build)."""
        caps = law_caps(controller, outside)
        if caps is None:
            raise ConfigError(f"controller {controller!r} is an outside law: build it first (plugins.build)")
        self.name, self.outside, self.caps = controller, outside, caps

    def build(self, K: np.ndarray, desired_px: np.ndarray, desired_depth: float, config: IBVSConfig,
              dofs: tuple[str, ...], goal: np.ndarray | None, roi) -> Law:
        """The law on s* = desired_px (pinhole pixels), or on the goal image's region `roi` for a law on the images."""
        if self.outside is not None:
            return OutsideLaw(self.outside, config, dofs)
        return BUILT_IN[self.name][1](K, desired_px, desired_depth, config, dofs, goal, roi)
