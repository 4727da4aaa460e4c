"""The closed loop's small parts, apart so that servo/loop.py reads as the loop: the settings it resolves, the servo
task's two answers (Observation, Truth: here, beneath servo/task.py, so that the loop's config may read this module),
what one step carries between its phases, and the stopwatch of its timings. No servo module is imported here."""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hvs_sim.render.camera import CameraPose
from hvs_sim.tracking import Track

if TYPE_CHECKING:
    from hvs_sim.control.feature_filter import FeatureFilter
    from hvs_sim.control.laws.ibvs import Law
    from hvs_sim.control.safety import Envelope, SafetyGate

# where the tracked features' template comes from (LoopConfig.template_from): the run's first frame ("start"),
# or an image taken with the camera at the reference pose before the run ("goal": teach-by-showing)
TEMPLATE_VIEWS = ("start", "goal")
# LoopConfig.goal_frames' default: frames averaged into the goal image (2 s of a 30 Hz camera held at the goal), so
# that the template freezes little of the camera's noise (docs/tuning.md)
GOAL_FRAMES = 64
NEAR_GOAL_PX = 2.0  # LoopConfig.near_goal_px's default: the features this near s* switch to the grown template
# LoopConfig.near_goal_inset_px's default: the loop grows the near-goal template itself (near_goal_growth)
NEAR_GOAL_AUTO = "auto"
NEAR_GOAL_OFF = "off"  # its spelling for one template throughout (None), as the command line gives it
# the share of the goal image the automatic near-goal template covers: the target's outline grown alike on every
# side until its box holds this much of the image: a share rather than a fixed growth, which left a larger target's
# box too large (the measurements: docs/tuning.md, NEAR_GOAL_AREA)
NEAR_GOAL_AREA = 0.25
NEAR_GOAL_MIN_GROWTH_PX = 8  # a box that can grow less than this adds too little: the loop keeps one template
# LoopConfig.near_goal_scale's default for a built-in tracker: its features on the near-goal template cost what the
# template's area does, and the coarser scale ended no further from the goal (docs/tuning.md, NEAR_GOAL_SCALE)
NEAR_GOAL_SCALE = 0.25


@dataclass(frozen=True)
class ResolvedLoop:
    """LoopConfig's "None: decided by the loop" settings as this loop decided them (ServoLoop.resolved, run.json)."""

    warp: str  # the features' warp model: the tracker's; "homography" for ground truth and none (perspective corners)
    dofs: tuple[str, ...]  # the DOFs commanded: IBVSConfig.dofs, else the outside law's or policy's, else the warp's
    damping: float  # IBVSConfig.damping: TRACKED_6DOF_DAMPING for tracked corners on six DOF under IBVS, else 0
    filter_alpha: float  # LoopConfig.feature_filter: FEATURE_FILTER_ALPHA for tracked corners on six DOF, else 0 (off)
    template_from: str  # "goal" or "start" (template_view; "goal" for a law on the images or a policy)
    goal_frames: int | None  # frames averaged into the goal image: None with a start template, 1 for the oracle
    # the template's inset (px); None: decided at step 0 from the target's box in the goal image (default_inset)
    roi_inset_px: int | None
    # the near-goal template's growth (LoopConfig.near_goal_inset_px): a number, NEAR_GOAL_AUTO (decided at step 0 by
    # near_goal_growth) or None (one template); near_goal_off: why NEAR_GOAL_AUTO does not apply to this run
    near_goal: int | str | None = None
    near_goal_off: str | None = None
    near_goal_scale: float | None = None  # the working scale of the second tracker built for it (None: the loop's own)


@dataclass(frozen=True)
class Observation:
    """What a controller may read at a step (ServoTask.observe)."""

    frame: np.ndarray | None  # H×W×3 uint8 from the camera (None: not asked for, rendering costs)
    joints: np.ndarray  # joint angles (rad)
    joint_velocities: np.ndarray  # rad/s
    camera: CameraPose  # world from camera (OpenCV axes), the joints' forward kinematics
    K: np.ndarray  # 3×3 intrinsics
    time: float  # s since the episode began


@dataclass(frozen=True)
class Truth:
    """What grades a step and no controller reads: the simulator's own answer (ServoTask.truth)."""

    corners: np.ndarray  # the target's corners in the camera's image (px, through the lens)
    occlusion: float  # share of the target hidden (NaN: not evaluated)
    pose_error: np.ndarray  # the camera's error to the reference pose (scene.world.Scene.pose_error)


@dataclass
class Capture:
    """What a step reads from the task at its state (servo/step.py: capture): the observation control reads, the truth
    that grades it (never given to control), and what the recording shows."""

    obs: Observation  # its frame None when nothing reads the frames (ServoLoop.renders_frames)
    truth: Truth
    people: list
    arm: tuple | None
    depths: np.ndarray | None
    timings: dict[str, float]  # render, ground_truth
    depths_ms: float  # the true depths (IBVSConfig.depth="true"): control's input, counted as control


@dataclass(frozen=True)
class Template:
    """A template's box in the goal image and what follows from it (LoopConfig.near_goal_inset_px's grown one)."""

    roi: tuple[int, int, int, int]  # (x, y, w, h)
    corners: np.ndarray  # its corners: the points the features are
    inset: int  # px the box lies inside the target's outline (negative: grown beyond it)
    desired: np.ndarray  # s*: those corners at the reference pose, in the camera's image


@dataclass
class Episode:
    """What step 0 fixes for the episode (ServoLoop.step_zero; the template's fields change once, at the switch to
    near_goal), and what is carried from step to step."""

    flag0: np.ndarray  # the target's corners in the template's image
    roi: tuple[int, int, int, int]  # the template's box in that image (x, y, w, h), inset
    roi0: np.ndarray  # its corners: the points the features are
    inset: int  # px the box lies inside the target's outline
    desired: np.ndarray  # s*: the features at the reference pose, in the camera's image
    template_frame: np.ndarray | None  # the first frame or the goal image (None: the oracle from the first frame)
    goal: np.ndarray | None  # the goal image (None with a start template)
    controller: Law | None  # the servo law: a built-in or an outside one (None: a policy's episode)
    feature_filter: FeatureFilter | None  # None: off
    gate: SafetyGate  # the safety rule's gate
    envelope: Envelope  # the workspace the camera may not leave
    carrier: FeatureFilter | None  # the last measurement carried by the camera's motion (the gate's jump test; None: no tracker)
    near_goal: Template | None = None  # the grown template switched to near the goal (None: one template throughout)
    camera_prev: CameraPose | None = None  # the camera at the step before: the camera's own motion between frames
    grow_from: np.ndarray | None = None  # the homography to seed the grown template at: the switch is due next step
    grown_at: int | None = None  # the step the grown template took over
    held_because: str | None = None  # why the gate holds the arm this step (None: it servos)
    aborted: str | None = None  # why the episode ended: the next command would have left the envelope


@dataclass
class Measured:
    """A step's features: the tracker's or the oracle's, then as control used them."""

    track: Track | None
    truth: np.ndarray  # where the features truly are (the target's true corners carried into the template's box)
    tracked: np.ndarray  # the tracker's (or oracle's) corners, graded against the truth
    features: np.ndarray  # the corners the controller used (after the feature filter, in the camera's image)
    mode: str
    fault: str | None


def frozen(a):
    """A read-only copy for outside code (a law, a policy): nothing it does to it reaches the loop's state."""
    if a is None:
        return None
    out = np.array(a, copy=True)
    out.flags.writeable = False
    return out


class Stopwatch:
    """Milliseconds since it was started (or since the last lap)."""

    def __init__(self):
        self.t0 = time.perf_counter()

    def ms(self) -> float:
        return 1e3 * (time.perf_counter() - self.t0)

    def lap(self) -> float:
        """ms() and start again from now: consecutive laps leave no gap between them."""
        now = time.perf_counter()
        out, self.t0 = 1e3 * (now - self.t0), now
        return out


@contextmanager
def lap(timings: dict[str, float], key: str):
    """Write the block's milliseconds into timings[key] (not when it raises: the step is then abandoned)."""
    watch = Stopwatch()
    yield
    timings[key] = watch.ms()
