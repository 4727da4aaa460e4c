"""The servo's safety rule: a loop that no longer sees holds still, and the camera never leaves its workspace.

Two parts with explicit state, for every tracker and law, built-in or outside (the loop applies them to whatever
twist the law or policy returns):

- `SafetyGate` decides from the measurement alone whether the loop still sees the target: a tracker that is lost,
  a prediction that has lasted longer than `max_predict_s`, a confidence under `min_confidence` (an outside tracker
  that declares none counts as sure, and is judged by the other checks), features that leave the image, a quad
  whose area is implausible against s*'s (`max_area_ratio`) or that jumped further than the camera's own motion
  explains (`max_jump_px`). A prediction is servoed on at a speed that falls linearly to zero at `max_predict_s`,
  and with the camera's travel since the last aligned measurement to zero at `max_predict_mm` (and its turn at
  `max_predict_deg`): a guess moves the camera a bounded distance however fast the servo was going when the
  target was hidden (v(1 - d/D) approaches D, never passes it). While it does not see, the commanded twist ramps down to zero within
  `decay_s` along the last twist it trusted (a controlled stop, as an industrial arm's stop category 2), and the camera holds while
  the tracker keeps searching. Servoing resumes once `resume_frames` consecutive aligned measurements agree within
  `resume_px` of each other with the camera held: a target found again stays where it was found.
- `Envelope` is the workspace: the camera stays within `envelope_margin_m` of the larger of its start's distance to
  the taught goal, measured from the goal and from the start, and within `envelope_margin_deg` of the start's
  rotation to the goal. A command that would carry the camera out within one step ends the episode as aborted,
  with the reason. The joints' own margins are the arm driver's (control/arm.py: motion toward a limit is stopped).

What the camera pose is: forward kinematics of the joints, what a real arm gives; the goal is the pose the arm was
taught at. Neither reads the simulator's truth about the target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from hvs_sim.geometry import rotation_vector
from hvs_sim.validate import check_flags, check_number

# the bounds' defaults, chosen on dev seeds (docs/tuning.md, "The safety rule")
MAX_PREDICT_S = 0.5
# how far a prediction may carry the camera: half the 20 mm the camera may drift while the target is hidden, the
# other half left to the aligned steps under partial occlusion and the controlled stop; the turn that moves the
# target's image about as much at the 0.8 m standoff (2° ≈ 28 mm of arc)
MAX_PREDICT_MM = 10.0
MAX_PREDICT_DEG = 2.0
MIN_CONFIDENCE = 0.05
MAX_AREA_RATIO = 16.0  # 4× the side: a start at 0.4 m of a 0.8 m standoff sees it 2× as wide (4× the area)
MAX_JUMP_PX = 40.0
DECAY_S = 0.2
RESUME_FRAMES = 3
RESUME_PX = 2.0
ENVELOPE_MARGIN_M = 0.10
ENVELOPE_MARGIN_DEG = 20.0

# why the gate closed (StepRecord.held_because), the first that applies
LOST, FAULT, PREDICTED, UNSURE, OUT_OF_IMAGE, IMPLAUSIBLE, REACQUIRING = (
    "lost", "fault", "predicted too long", "low confidence", "features out of the image", "implausible features",
    "re-acquiring")


@dataclass(frozen=True)
class SafetyConfig:
    """The safety rule's bounds (LoopConfig.safety). `enabled=False` turns the gate off (the loop servos on whatever
    it is given), for ablations only; the envelope is never turned off."""

    enabled: bool = True
    max_predict_s: float = MAX_PREDICT_S  # a measurement predicted longer than this: hold
    max_predict_mm: float = MAX_PREDICT_MM  # predictions carry the camera at most this far from the last aligned pose
    max_predict_deg: float = MAX_PREDICT_DEG  # ... and turn it at most this much
    min_confidence: float = MIN_CONFIDENCE  # the tracker's Track.confidence under this: hold
    max_area_ratio: float = MAX_AREA_RATIO  # the features' quad larger or smaller than s*'s by this factor: hold
    max_jump_px: float = MAX_JUMP_PX  # a corner further than this from where the camera's motion carries it: hold
    decay_s: float = DECAY_S  # the twist ramps to zero over this time once the gate closes
    resume_frames: int = RESUME_FRAMES  # consecutive aligned measurements that re-open it ...
    resume_px: float = RESUME_PX  # ... agreeing with each other within this (mean corner distance)
    envelope_margin_m: float = ENVELOPE_MARGIN_M
    envelope_margin_deg: float = ENVELOPE_MARGIN_DEG

    def __post_init__(self):
        check_flags(self, ("enabled",))
        check_number("safety max_predict_s", self.max_predict_s, 0)
        check_number("safety max_predict_mm", self.max_predict_mm, 0, lo_open=True)
        check_number("safety max_predict_deg", self.max_predict_deg, 0, 180, lo_open=True)
        check_number("safety min_confidence", self.min_confidence, 0, 1)
        check_number("safety max_area_ratio", self.max_area_ratio, 1, lo_open=True)
        check_number("safety max_jump_px", self.max_jump_px, 0, lo_open=True)
        check_number("safety decay_s", self.decay_s, 0)
        check_number("safety resume_frames", self.resume_frames, 1, integer=True)
        check_number("safety resume_px", self.resume_px, 0, lo_open=True)
        check_number("safety envelope_margin_m", self.envelope_margin_m, 0, lo_open=True)
        check_number("safety envelope_margin_deg", self.envelope_margin_deg, 0, 180, lo_open=True)


def quad_area(pts: np.ndarray) -> float:
    """Signed area (px²) of a quad's corners in order: positive for TL, TR, BR, BL in the image, negative crossed back."""
    return float(cv2.contourArea(np.asarray(pts, np.float32), oriented=True))


class SafetyGate:
    """Whether the loop still sees, frame by frame, and the factor its twist is scaled by (see the module)."""

    def __init__(self, config: SafetyConfig, fps: float, desired_px: np.ndarray, width: int, height: int):
        self.config, self.dt = config, 1.0 / fps
        self.size = np.array([width - 1, height - 1], float)
        self.set_desired(desired_px)
        self.predict_run = 0  # consecutive predicted measurements
        self.closed_because: str | None = None  # None: the gate is open (servoing)
        self.agreeing: list[np.ndarray] = []  # the aligned measurements since the gate closed, while they agree
        self.factor = 1.0  # what the law's twist is scaled by
        self.trusted_twist = np.zeros(6)  # the last twist commanded with the gate open: the controlled stop's direction
        self.aligned_pose: tuple[np.ndarray, np.ndarray] | None = None  # the camera (t, R) at the last aligned step
        self.predicted_share = 0.0  # the share of the prediction's budget (time, travel, turn) spent: 1 = all

    def set_desired(self, desired_px: np.ndarray) -> None:
        """s* (the near-goal template's, after the switch): the reference for the quad's plausible area."""
        self.desired_area = abs(quad_area(np.asarray(desired_px, float)))

    def _why_not(self, px: np.ndarray | None, mode: str, confidence: float, fault: bool,
                 jump_px: float | None) -> str | None:
        """Why this measurement is not one to servo on (None: it is)."""
        c = self.config
        if fault:
            return FAULT
        if px is None:  # no features (the oracle, a law on the images, a policy): only a fault stops it
            return None
        if mode == "lost":
            return LOST
        if mode == "predict" and self.predicted_share > 1.0:
            return PREDICTED
        if confidence < c.min_confidence:
            return UNSURE
        if not np.all(np.isfinite(px)) or np.any(px < 0) or np.any(px > self.size):
            return OUT_OF_IMAGE
        area = quad_area(px)
        ratio = area / self.desired_area if self.desired_area > 0 else 0.0
        if not (1.0 / c.max_area_ratio <= ratio <= c.max_area_ratio):  # also a flipped (negative) or collapsed quad
            return IMPLAUSIBLE
        if jump_px is not None and jump_px > c.max_jump_px:
            return IMPLAUSIBLE
        return None

    def _spend(self, mode: str, camera) -> None:
        """The share of the prediction's budget spent: the longest of its time, the camera's travel and its turn
        since the last aligned measurement (travel and turn only where the camera pose is given)."""
        c = self.config
        self.predict_run = self.predict_run + 1 if mode == "predict" else 0
        if camera is not None and mode == "align":
            self.aligned_pose = (np.array(camera.t, float), np.array(camera.R, float))
        if mode != "predict":
            self.predicted_share = 0.0
            return
        share = self.predict_run * self.dt / c.max_predict_s if c.max_predict_s > 0 else math.inf
        if camera is not None and self.aligned_pose is not None:
            t0, R0 = self.aligned_pose
            share = max(share, 1e3 * float(np.linalg.norm(np.asarray(camera.t, float) - t0)) / c.max_predict_mm,
                        rotation_deg(camera.R, R0) / c.max_predict_deg)
        self.predicted_share = share

    def update(self, px: np.ndarray | None, mode: str, confidence: float | None, fault: bool,
               jump_px: float | None = None, camera=None) -> str | None:
        """Take a step's measurement and return why the loop holds (None: it servos); updates `factor`. px: the
        tracker's corners in the image (None: a run without features); confidence: the tracker's (None: it
        declares none); jump_px: the largest corner distance to where the camera's own motion carries the last
        measurement (None where unknown); camera: its pose from forward kinematics (t in m, R), for the travel a
        prediction may cause (None: the prediction is bounded by its time alone)."""
        c = self.config
        self._spend(mode, camera)
        px = None if px is None else np.asarray(px, float)
        why = self._why_not(px, mode, 1.0 if confidence is None else float(confidence), fault, jump_px)
        if self.closed_because is None:
            if why is not None:
                self.closed_because, self.agreeing = why, []
        elif why is None and px is None:  # nothing to verify: the fault has passed
            self.closed_because = None
        elif why is None and mode == "align" and px is not None:
            if self.agreeing and np.linalg.norm(px - self.agreeing[0], axis=1).mean() > c.resume_px:
                self.agreeing = []  # not where the first of them was: start counting again from this one
            self.agreeing.append(px)
            if len(self.agreeing) >= c.resume_frames:
                self.closed_because, self.agreeing = None, []
            else:
                self.closed_because = REACQUIRING
        else:
            self.closed_because, self.agreeing = why or self.closed_because, []
        if not c.enabled:
            self.closed_because = None
        step = self.dt / c.decay_s if c.decay_s > 0 else 1.0
        if self.closed_because is None:
            self.factor = min(1.0, self.factor + step)
            if mode == "predict" and c.enabled:  # a guess is servoed on ever more slowly, to a stop at its budget
                self.factor = min(self.factor, max(0.0, 1.0 - self.predicted_share))
        else:  # a fault stops at once: there is no law's answer at all; a spent prediction has ramped down already
            self.factor = 0.0 if self.closed_because in (FAULT, PREDICTED) else max(0.0, self.factor - step)
        return self.closed_because

    def twist(self, law_twist: np.ndarray | None) -> np.ndarray:
        """The twist to command: the law's while the gate is open (ramping back up after a hold), else the last
        trusted one ramping down to zero (the law's answer on features it cannot trust is not followed)."""
        if self.closed_because is None:
            out = np.zeros(6) if law_twist is None else np.asarray(law_twist, float)
            self.trusted_twist = out
            return out * self.factor
        return self.trusted_twist * self.factor


class Envelope:
    """The workspace the camera may not leave (see the module): fixed at the episode's start from the camera's pose
    then (forward kinematics) and the taught goal."""

    def __init__(self, config: SafetyConfig, start_pos, start_R, goal_pos, goal_R):
        self.config = config
        self.start_pos, self.goal_pos, self.goal_R = (np.asarray(a, float) for a in (start_pos, goal_pos, goal_R))
        d0 = float(np.linalg.norm(self.start_pos - self.goal_pos))
        self.radius_m = d0 + config.envelope_margin_m
        self.max_deg = rotation_deg(start_R, goal_R) + config.envelope_margin_deg

    def check(self, pos, R, twist_cam: np.ndarray, dt: float) -> str | None:
        """Why the camera at (pos, R) commanded `twist_cam` (camera frame) would leave within one step; None: it
        stays inside."""
        R = np.asarray(R, float)
        nxt = np.asarray(pos, float) + R @ np.asarray(twist_cam[:3], float) * dt
        from_goal = float(np.linalg.norm(nxt - self.goal_pos))
        from_start = float(np.linalg.norm(nxt - self.start_pos))
        w = R @ np.asarray(twist_cam[3:], float) * dt
        R_next = _rotation(w) @ R
        deg = rotation_deg(R_next, self.goal_R)
        if from_goal > self.radius_m:
            return (f"the camera would be {1e3 * from_goal:.0f} mm from the goal, beyond the envelope's "
                    f"{1e3 * self.radius_m:.0f} mm")
        if from_start > self.radius_m:
            return (f"the camera would be {1e3 * from_start:.0f} mm from its start, beyond the envelope's "
                    f"{1e3 * self.radius_m:.0f} mm")
        if deg > self.max_deg:
            return f"the camera would be turned {deg:.1f}° from the goal, beyond the envelope's {self.max_deg:.1f}°"
        return None


def rotation_deg(Ra, Rb) -> float:
    """The angle (degrees) of the rotation between two rotation matrices."""
    return math.degrees(float(np.linalg.norm(rotation_vector(np.asarray(Ra, float).T @ np.asarray(Rb, float)))))


def _rotation(w: np.ndarray) -> np.ndarray:
    """The rotation by the rotation vector w (OpenCV's Rodrigues)."""
    return cv2.Rodrigues(np.asarray(w, float).reshape(3, 1))[0]
