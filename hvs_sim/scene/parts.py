"""MJCF parts of the world. Each part builds its own fragment and keeps handles to its elements."""

from __future__ import annotations

import mujoco
import numpy as np
from dm_control import mjcf

from hvs_sim.scene.flag_art import FLAG_NAMES, flag_path
from hvs_sim.scene.people import OCCLUDER_GROUP, Person  # noqa: F401  (people live in people.py)


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

