"""IBVS written from the textbook against hvs_sim's ControlInput (v = −λ L⁺ e, L at the desired features), and a
law that answers malformed twists."""

import numpy as np


def point_interaction(xy, Z):
    x, y = xy[:, 0], xy[:, 1]
    L = np.zeros((2 * len(xy), 6))
    L[0::2] = np.stack([-1 / Z, 0 * x, x / Z, x * y, -(1 + x * x), y], 1)
    L[1::2] = np.stack([0 * x, -1 / Z, y / Z, 1 + y * y, -x * y, -x], 1)
    return L


class PlainIBVS:
    def __init__(self, gain: float = 1.0):
        self.gain = gain

    def compute(self, inp):
        if inp.mode == "lost":
            return np.zeros(6)
        e = (inp.features - inp.desired).reshape(-1)
        L = point_interaction(inp.desired, np.full(len(inp.desired), inp.desired_depth))
        return -self.gain * (np.linalg.pinv(L) @ e)


def make(**settings):
    return PlainIBVS(**settings)


class Broken:
    dofs = ("vx", "vy", "vz", "wz")

    def __init__(self):
        self.n = 0

    def compute(self, inp):
        self.n += 1
        return [0.0] * 5 if self.n % 2 else np.array([np.inf, 0, 0, 0, 0, 0])


def make_broken():
    return Broken()
