"""An image-to-velocity policy: it finds the goal image's target in the frame by normalised cross-correlation and
drives its centre and size to the goal's (vx, vy, vz), as a simple learned policy's output would."""

import cv2
import numpy as np


class TemplatePolicy:
    dofs = ("vx", "vy", "vz")

    def __init__(self, gain: float = 1.0):
        self.gain = gain

    def reset(self, obs):
        x0, y0 = np.floor(obs.desired_px.min(0)).astype(int)
        x1, y1 = np.ceil(obs.desired_px.max(0)).astype(int)
        grey = cv2.cvtColor(obs.goal_image, cv2.COLOR_RGB2GRAY)
        self.template = grey[y0:y1, x0:x1]
        self.goal_centre = obs.desired_px.mean(0)

    def act(self, obs):
        grey = cv2.cvtColor(obs.image, cv2.COLOR_RGB2GRAY)
        score = cv2.matchTemplate(grey, self.template, cv2.TM_CCOEFF_NORMED)
        _, best, _, (x, y) = cv2.minMaxLoc(score)
        if best < 0.5:
            return np.zeros(6)
        centre = np.array([x + self.template.shape[1] / 2 - 0.5, y + self.template.shape[0] / 2 - 0.5])
        e = (centre - self.goal_centre) / obs.K[0, 0]
        return np.array([self.gain * 0.8 * e[0], self.gain * 0.8 * e[1], 0.0, 0.0, 0.0, 0.0])


def make(**settings):
    return TemplatePolicy(**settings)
