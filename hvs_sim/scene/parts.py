"""MJCF parts of the world. Each part builds its own fragment and keeps handles to its elements."""

from __future__ import annotations

import mujoco
import numpy as np
from dm_control import mjcf

from hvs_sim.scene.flag_art import FLAG_NAMES, flag_path

OCCLUDER_GROUP = 3  # geom group of people, so that renders can hide them


class FlagWall:
    """A board with a 3×5 grid of textured flags on a mocap body; the target flag sits in the centre.

    The body origin is the centre of the target flag's front face; the front faces the −X side.
    """

    ROWS, COLS = 3, 5
    FLAG_W, FLAG_H = 0.15, 0.10  # metres (3:2 like the textures)
    PITCH_Y, PITCH_Z = 0.19, 0.135
    THICK = 0.002

    def __init__(self, root: mjcf.RootElement, target_flag: str):
        self.body = root.worldbody.add("body", name="flag_wall", mocap=True)
        order = [n for n in FLAG_NAMES if n != target_flag]
        centre = (self.ROWS // 2) * self.COLS + self.COLS // 2
        order.insert(centre, target_flag)
        w, h = self.COLS * self.PITCH_Y + 0.06, self.ROWS * self.PITCH_Z + 0.06
        board_tex = root.asset.add("texture", name="board", type="2d", builtin="flat", width=256, height=256,
                                   rgb1=[0.82, 0.80, 0.74], rgb2=[0.6, 0.58, 0.55], mark="random", random=0.04)
        board_mat = root.asset.add("material", name="board", texture=board_tex, texrepeat=[4, 4])
        y0 = (self.COLS // 2) * self.PITCH_Y
        z0 = (self.ROWS // 2) * self.PITCH_Z
        self.body.add("geom", name="board", type="box", size=[0.01, w / 2, h / 2],
                      pos=[2 * self.THICK + 0.01, y0 - (self.COLS - 1) * self.PITCH_Y / 2, z0 - (self.ROWS - 1) * self.PITCH_Z / 2],
                      material=board_mat, contype=0, conaffinity=0)
        self.flags = {}
        for k, name in enumerate(order[: self.ROWS * self.COLS]):
            r, c = divmod(k, self.COLS)
            tex = root.asset.add("texture", name=f"flag_{name}", type="2d", file=str(flag_path(name)), hflip=True)
            mat = root.asset.add("material", name=f"flag_{name}", texture=tex, specular=0.05, shininess=0.05)
            # viewer looks along +X: image right is world −Y, so column c sits at y = y0 − c·pitch
            self.flags[name] = self.body.add(
                "geom", name=f"flag_{name}", type="box", size=[self.THICK, self.FLAG_W / 2, self.FLAG_H / 2],
                pos=[self.THICK, y0 - c * self.PITCH_Y, z0 - r * self.PITCH_Z], material=mat,
                contype=0, conaffinity=0)
        self.target = self.flags[target_flag]

    @classmethod
    def corner_offsets(cls) -> np.ndarray:
        """Target front-face corners in the flag geom frame: TL, TR, BR, BL as seen by the camera."""
        sx, sy, sz = cls.THICK, cls.FLAG_W / 2, cls.FLAG_H / 2
        return np.array([[-sx, sy, sz], [-sx, -sy, sz], [-sx, -sy, -sz], [-sx, sy, -sz]])


class Person:
    """A person-like body of capsules and boxes on a mocap body (kinematic, no collisions).

    Body frame: origin on the floor between the feet, +X the walking direction, +Z up.
    """

    HALF_DEPTH = 0.12  # half extent front to back: what the camera sees while it walks past in profile
    HALF_WIDTH = 0.28  # half extent shoulder to shoulder, arms included: what it sees when facing the camera

    def __init__(self, root: mjcf.RootElement, index: int, rng: np.random.Generator):
        shirt = np.r_[rng.uniform(0.1, 0.9, 3), 1.0]
        trousers = np.r_[rng.uniform(0.05, 0.4, 3), 1.0]
        skin = np.r_[np.array([0.85, 0.65, 0.5]) * rng.uniform(0.55, 1.0), 1.0]
        hair = np.r_[rng.uniform(0.05, 0.3) * np.ones(3), 1.0]
        self.body = root.worldbody.add("body", name=f"person{index}", mocap=True)
        common = dict(contype=0, conaffinity=0, group=OCCLUDER_GROUP)
        for side in (1, -1):
            self.body.add("geom", type="capsule", fromto=[0, side * 0.09, 0.07, 0, side * 0.09, 0.9], size=[0.065], rgba=trousers, **common)
            self.body.add("geom", type="box", pos=[0.04, side * 0.09, 0.03], size=[0.12, 0.05, 0.03], rgba=[0.1, 0.1, 0.1, 1], **common)
            self.body.add("geom", type="capsule", fromto=[0, side * 0.235, 1.47, 0.03, side * 0.235, 0.95], size=[0.045], rgba=shirt, **common)
            self.body.add("geom", type="sphere", pos=[0.035, side * 0.235, 0.88], size=[0.05], rgba=skin, **common)
        self.body.add("geom", type="box", pos=[0, 0, 1.22], size=[self.HALF_DEPTH, 0.19, 0.30], rgba=shirt, **common)
        self.body.add("geom", type="capsule", fromto=[0, 0, 1.5, 0, 0, 1.6], size=[0.05], rgba=skin, **common)
        self.body.add("geom", type="sphere", pos=[0.01, 0, 1.7], size=[0.105], rgba=skin, **common)
        self.body.add("geom", type="ellipsoid", pos=[-0.015, 0, 1.75], size=[0.1, 0.1, 0.07], rgba=hair, **common)


class HandheldRig:
    """A free camera on a mocap body: the hand-held set-up of the paper's evaluation videos."""

    def __init__(self, root: mjcf.RootElement, fovy: float):
        self.body = root.worldbody.add("body", name="handheld", mocap=True)
        self.camera = self.body.add("camera", name="eye", fovy=fovy)


class ArmRig:
    """Kinova Jaco (dm_control, velocity actuators) on a pedestal with an eye-in-hand wrist camera.

    The camera looks along the wrist site's +Z. Arm bodies are gravity-compensated, as the real
    arm's firmware does, so that zero velocity commands hold the pose.
    """

    BASE_HEIGHT = 0.9

    def __init__(self, root: mjcf.RootElement, fovy: float):
        from dm_control.entities.manipulators.kinova import JacoArm

        self.arm = JacoArm()
        for body in self.arm.mjcf_model.find_all("body"):
            body.gravcomp = 1.0
        wrist = self.arm.wrist_site
        # camera frame = site frame rotated 180° about X: MuJoCo cameras look along their −Z
        q_site = np.asarray(wrist.quat, float)
        q_flip = np.array([0.0, 1.0, 0.0, 0.0])
        q_cam = np.zeros(4)
        mujoco.mju_mulQuat(q_cam, q_site, q_flip)
        self.camera = wrist.parent.add("camera", name="eye", pos=wrist.pos, quat=q_cam, fovy=fovy)
        self.camera_site = wrist.parent.add("site", name="eye_site", pos=wrist.pos, quat=q_cam, size=[0.005], group=4)
        root.worldbody.add("geom", name="pedestal", type="cylinder", size=[0.08, self.BASE_HEIGHT / 2],
                           pos=[0, 0, self.BASE_HEIGHT / 2], rgba=[0.3, 0.3, 0.32, 1])
        frame = root.attach(self.arm.mjcf_model)
        frame.pos = [0, 0, self.BASE_HEIGHT]
        self.joints = self.arm.joints
        self.actuators = self.arm.actuators

