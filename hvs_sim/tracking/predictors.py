"""Motion predictors for the occlusion path: hold, constant velocity, and the GRU (paper Fig. 5).

All see the same thing: the last k confident translations (frame pixels). While the target is
hidden they roll out one frame at a time, feeding their own predictions back as history.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import torch

from hvs_sim.errors import ConfigError, choice_error

PREDICTORS = ("gru", "constant_velocity", "hold")


class MotionPredictor:
    name = "base"

    def __init__(self, history: int = 10):
        if not isinstance(history, int) or history < 3:
            raise ConfigError(f"predictor history must be an int >= 3, got {history!r}")
        self.k = history
        self.confident: deque[np.ndarray] = deque(maxlen=history)
        self.rollout: list[np.ndarray] = []

    def reset(self) -> None:
        self.confident.clear()
        self.rollout = []

    def observe(self, t: np.ndarray) -> None:
        """A confident translation (align path): it becomes history, and any rollout ends."""
        self.confident.append(np.asarray(t, float).copy())
        self.rollout = []

    def carry(self, t: np.ndarray) -> None:
        """A frame another source guessed (not confident): it continues the rollout, as this predictor's own guess
        would have, so that the next prediction is for the frame after it."""
        self.rollout.append(np.asarray(t, float).copy())

    def history(self) -> np.ndarray:
        return np.array((list(self.confident) + self.rollout)[-self.k:])

    def peek(self) -> np.ndarray:
        """The translation `predict` would give for the current frame, without rolling out."""
        h = self.history()
        return h[-1] + self._step(h) if len(h) >= 2 else (h[-1] if len(h) else np.zeros(2))

    def predict(self) -> np.ndarray:
        """Translation for the current frame (one step past the history), appended to the rollout."""
        nxt = self.peek()
        self.rollout.append(nxt)
        return nxt

    def _step(self, h: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


class HoldPredictor(MotionPredictor):
    name = "hold"

    def _step(self, h):
        return np.zeros(2)


class ConstantVelocityPredictor(MotionPredictor):
    """Mean displacement over the last `window` confident frames, continued."""

    name = "constant_velocity"

    def __init__(self, history: int = 10, window: int = 5):
        super().__init__(history)
        self.window = window

    def _step(self, h):
        conf = np.array(self.confident)
        if len(conf) < 2:
            return np.zeros(2)
        w = conf[-min(self.window + 1, len(conf)):]
        return (w[-1] - w[0]) / (len(w) - 1)


class GRUMotionPredictor(MotionPredictor):
    name = "gru"

    def __init__(self, history: int = 10, weights: str | None = None):
        super().__init__(history)
        from hvs_sim.tracking.nets.gru import UNIT_PX, load_gru

        self.net = load_gru(weights)
        self.unit = UNIT_PX

    def _step(self, h):
        d = np.diff(h, axis=0) / self.unit
        with torch.inference_mode():
            out = self.net(torch.from_numpy(d[None].astype(np.float32)))[0].double().numpy()
        return out * self.unit


def make_predictor(name: str, history: int = 10, gru_weights: str | None = None) -> MotionPredictor:
    if name == "gru":
        return GRUMotionPredictor(history, gru_weights)
    if name == "constant_velocity":
        return ConstantVelocityPredictor(history)
    if name == "hold":
        return HoldPredictor(history)
    raise choice_error("predictor", name, PREDICTORS)
