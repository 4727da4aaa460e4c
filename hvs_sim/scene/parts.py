"""MJCF parts of the world. Each part builds its own fragment and keeps handles to its elements."""

from __future__ import annotations

import cv2
import mujoco
import numpy as np
from dm_control import mjcf

from hvs_sim.errors import ConfigError
from hvs_sim.scene.flag_art import FLAG_NAMES, flag_path
from hvs_sim.scene.people import OCCLUDER_GROUP, Person  # noqa: F401  (people live in scene/people/)

TARGET_GROUP = 1  # geom group of the target picture alone (shown like group 0), so that a render can show it and the
# people only: nothing else can be in front of it, and the occlusion count's segmentation render then shades little


class FlagWall:
    """A board with a 3×5 grid of pictures on a mocap body; the target sits in the centre.

    Each slot holds a flag (by name, from assets/flags) or an RGB image (posters, photos, natural
    textures). The target keeps its image's aspect ratio at `target_width` metres; the other slots
    are FLAG_W × FLAG_H. The body origin is the centre of the target's front face; the front faces −X.
    """

    ROWS, COLS = 3, 5
    FLAG_W, FLAG_H = 0.15, 0.10  # metres (3:2 like the textures)
    PITCH_Y, PITCH_Z = 0.19, 0.135
    THICK = 0.002

    def __init__(self, root: mjcf.RootElement, target: str | np.ndarray, others: list | None = None,
                 target_width: float = FLAG_W):
        """target: flag name or RGB image; others: the 14 other slots (flag names or images), row by row;
        None = the other flags in their usual order."""
        self.body = root.worldbody.add("body", name="flag_wall", mocap=True)
        n_slots = self.ROWS * self.COLS
        centre = (self.ROWS // 2) * self.COLS + self.COLS // 2
        if others is None:
            others = [n for n in FLAG_NAMES if not isinstance(target, str) or n != target]
        order = list(others[: n_slots - 1])
        order.insert(centre, target)
        aspect = self.FLAG_H / self.FLAG_W if isinstance(target, str) else target.shape[0] / target.shape[1]
        self.target_size = (float(target_width), float(target_width) * aspect)  # (width, height) m
        # a target larger than a flag spreads the grid by the difference, so neighbours keep their gaps
        pitch_y = self.PITCH_Y + max(0.0, self.target_size[0] - self.FLAG_W)
        pitch_z = self.PITCH_Z + max(0.0, self.target_size[1] - self.FLAG_H)
        w, h = self.COLS * pitch_y + 0.06, self.ROWS * pitch_z + 0.06
        board_tex = root.asset.add("texture", name="board", type="2d", builtin="flat", width=256, height=256,
                                   rgb1=[0.82, 0.80, 0.74], rgb2=[0.6, 0.58, 0.55], mark="random", random=0.04)
        board_mat = root.asset.add("material", name="board", texture=board_tex, texrepeat=[4, 4])
        y0 = (self.COLS // 2) * pitch_y
        z0 = (self.ROWS // 2) * pitch_z
        self.flags = {}
        for k, item in enumerate(order):
            r, c = divmod(k, self.COLS)
            name = item if isinstance(item, str) else f"picture{k}"
            source = str(flag_path(item)) if isinstance(item, str) else mjcf.Asset(_png_bytes(item), ".png")
            tex = root.asset.add("texture", name=f"flag_{name}", type="2d", file=source, hflip=True)
            mat = root.asset.add("material", name=f"flag_{name}", texture=tex, specular=0.05, shininess=0.05)
            half_w, half_h = (self.target_size[0] / 2, self.target_size[1] / 2) if k == centre else \
                (self.FLAG_W / 2, self.FLAG_H / 2)
            # viewer looks along +X: image right is world −Y, so column c sits at y = y0 − c·pitch
            self.flags[name] = self.body.add(
                "geom", name=f"flag_{name}", type="box", size=[self.THICK, half_w, half_h],
                pos=[self.THICK, y0 - c * pitch_y, z0 - r * pitch_z], material=mat,
                contype=0, conaffinity=0, group=TARGET_GROUP if k == centre else 0)
            if k == centre:
                self.target = self.flags[name]
        # after the pictures in front of it: drawn later, its hidden part is not shaded (Scene builds front to back)
        self.body.add("geom", name="board", type="box", size=[0.01, w / 2, h / 2],
                      pos=[2 * self.THICK + 0.01, y0 - (self.COLS - 1) * pitch_y / 2, z0 - (self.ROWS - 1) * pitch_z / 2],
                      material=board_mat, contype=0, conaffinity=0)

    def corner_offsets(self) -> np.ndarray:
        """Target front-face corners in the target geom's frame: TL, TR, BR, BL as seen by the camera."""
        sx, sy, sz = self.THICK, self.target_size[0] / 2, self.target_size[1] / 2
        return np.array([[-sx, sy, sz], [-sx, -sy, sz], [-sx, -sy, -sz], [-sx, sy, -sz]])


def _png_bytes(rgb: np.ndarray) -> bytes:
    """An RGB image as PNG bytes, for MuJoCo's in-memory assets (nothing is written to disk)."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:  # pragma: no cover - a uint8 RGB image always encodes
        raise ConfigError("could not encode a wall picture as PNG")
    return buf.tobytes()


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
    BASE_X = 0.0  # along the camera's viewing direction (world +X), relative to the world origin

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
                           pos=[self.BASE_X, 0, self.BASE_HEIGHT / 2], rgba=[0.3, 0.3, 0.32, 1])
        frame = root.attach(self.arm.mjcf_model)
        frame.pos = [self.BASE_X, 0, self.BASE_HEIGHT]
        self.joints = self.arm.joints
        self.actuators = self.arm.actuators

    @property
    def mjcf_model(self):
        return self.arm.mjcf_model

