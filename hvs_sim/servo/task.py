"""The servo task: one arm-mounted camera and one target, as dm_control's Task or a Gymnasium env holds a world and
what grades it. It owns the scene, its renderer, the arm's velocity driver, the goal (s*: the target's corners seen
from the reference pose) and the metrics. The closed loop (the agent: tracker, feature filter, law, safety) and the gym
env both step it, so that neither builds a world of its own.

What it gives back is split by type: an `Observation` holds what a controller may read (the frame, the joints, the
camera's pose from the joints' forward kinematics, K), a `Truth` what only grades it (the target's corners, the share of
it hidden, the pose error), so that ground truth stays off the control path by type rather than by convention.

Reset cost: an episode whose compiled model would be the same as the last one's (scene.world.model_key: the same
scenario, camera and people, the seed drawing nothing of the model) restarts on it (Scene.restart) instead of building
and compiling the scene and its rendering context again."""

from __future__ import annotations

import dataclasses

import numpy as np

from hvs_sim.control.arm import ArmDriver, JointCommand
from hvs_sim.errors import InputError, StateError
from hvs_sim.render.camera import CameraPose
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.scene.world import Scene, model_key
from hvs_sim.servo.parts import Observation, Truth
from hvs_sim.servo.teach import check_start_in_view, goal_image

__all__ = ["Observation", "ServoTask", "Truth", "World"]  # the task's two answers live in parts.py, which the loop reads


@dataclasses.dataclass(frozen=True)
class World:
    """The live episode's parts, none of them missing: what an agent that stepped a successful reset holds (the task's
    own attributes are None between episodes)."""

    scene: Scene
    renderer: Renderer
    arm: ArmDriver
    desired: np.ndarray  # s*: the target's corners at the reference pose (px)


class ServoTask:
    """scene, renderer, arm, goal and metrics of one episode at a time: reset() starts one, step() moves the arm."""

    def __init__(self, scenario: Scenario, framebuffer: tuple[int, int] | None = None):
        """framebuffer: the offscreen size of a third-person view (Scene), when one is rendered."""
        self.scenario, self.framebuffer = scenario, framebuffer
        self.scene: Scene | None = None  # None until a reset succeeds
        self.renderer: Renderer | None = None
        self.arm: ArmDriver | None = None
        self.desired: np.ndarray | None = None  # s*: the target's corners at the reference pose (px)
        self.model_builds = 0  # scenes built and compiled (the rest of the resets restarted one)
        self._compiled: Scene | None = None  # the last episode's scene: its model and rendering context, for restart

    def reset(self, seed: int | None = None, scenario: Scenario | None = None,
              noise_seed: int | None = None) -> Observation:
        """Start an episode of `scenario` (default: the task's; `seed` replaces its seed, the look and the people).
        noise_seed: the camera's noise (None: the scenario's seed). ConfigError when the arm cannot reach the start
        pose or the target is not fully in view from it; the task then has no scene until a reset succeeds."""
        scen = self.scenario if scenario is None else scenario
        scen = scen if seed is None else dataclasses.replace(scen, seed=seed)
        self.scene = None
        if self._compiled is not None and model_key(scen) == model_key(self._compiled.scenario):
            self._compiled.restart(scen)
        else:
            self._compiled = None  # the old model's memory goes before the new one is built
            self._compiled = Scene(scen, framebuffer=self.framebuffer)
            self.model_builds += 1
        renderer = Renderer(self._compiled, noise_seed=noise_seed)
        check_start_in_view(self._compiled, renderer)
        self.scene, self.renderer, self.scenario = self._compiled, renderer, scen
        ref_pos, ref_R = self.scene.reference_pose()
        self.desired = renderer.project(CameraPose(ref_R, ref_pos), self.scene.target_corners_world())
        self.arm = ArmDriver(self.scene)
        return self.observe(frame=False)

    @property
    def world(self) -> World:
        """The live episode's scene, renderer, arm and s*; StateError before a reset succeeds or after close()."""
        if self.scene is None or self.renderer is None or self.arm is None or self.desired is None:
            raise StateError("the servo task has no episode: call reset() first")
        return World(self.scene, self.renderer, self.arm, self.desired)

    def _live(self) -> tuple[Scene, Renderer]:
        w = self.world
        return w.scene, w.renderer

    def observe(self, frame: bool = True) -> Observation:
        """What a controller may read now; the frame only when asked (it is rendered, with the camera's noise)."""
        scene, r = self._live()
        image = r.rgb() if frame else None
        return Observation(image, scene.joint_positions, scene.joint_velocities, r.camera_pose(), r.K, scene.time)

    def truth(self, occlusion: bool = True, counts: bool = False) -> Truth:
        """The step's truth (Renderer.ground_truth: occlusion=False renders nothing, NaN; counts=False: 0 without a
        render where no person can be over the target)."""
        scene, r = self._live()
        gt = r.ground_truth(occlusion=occlusion, counts=counts)
        return Truth(gt.corners, gt.occlusion, scene.pose_error())

    def error_px(self, truth: Truth) -> float:
        """The mean distance (px) of the target's corners to s*: what the task grades."""
        return float(np.linalg.norm(truth.corners - self.world.desired, axis=1).mean())

    def command(self, twist: np.ndarray) -> JointCommand:
        """The camera twist as joint velocities at the arm's configuration now (ArmDriver.command)."""
        return self.world.arm.command(twist)

    def advance(self, qdot: np.ndarray) -> None:
        """One physics step with the joints at these velocities (rad/s)."""
        self._live()[0].advance(qdot)

    def step(self, twist: np.ndarray | None = None, qdot: np.ndarray | None = None, frame: bool = True,
             occlusion: bool = True, counts: bool = False) -> tuple[Observation, Truth]:
        """One step: a camera twist (through the arm's driver) or joint velocities, then what follows from it (the
        frame, the occlusion and its counts as observe and truth take them)."""
        if twist is not None and qdot is None:
            qdot = self.command(twist).qdot
        elif twist is not None or qdot is None:
            raise InputError("give the step a twist or joint velocities (qdot), one of them")
        self.advance(qdot)
        return self.observe(frame), self.truth(occlusion, counts)

    def close(self) -> None:
        """Let the scene, its model and its rendering context go (a later reset builds them again)."""
        self.scene = self.renderer = self.arm = self._compiled = None

    def goal_image(self, frames: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(image, target corners) with the camera at the reference pose and the people left out (servo/teach.py):
        the mean of `frames` frames, or (None) one frame, as the gym env gives it."""
        scene, _ = self._live()
        if frames is not None:
            return goal_image(scene, frames)
        teacher = Renderer(scene, people=False)  # its own sensor state: the episode's frames are unchanged
        with scene.posed(scene.reference_configuration()):
            return teacher.rgb(), teacher.ground_truth(occlusion=False).corners
