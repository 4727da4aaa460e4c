"""The arms a wrist camera can ride on: one registry (ARMS) of what each is, and the rig that builds it.

The Kinova Jaco comes from dm_control (its entity, velocity actuators and torque limits). The Franka Panda, the
Universal Robots UR5e and the Kinova Gen3 are read as files from robosuite's model folder (MIT licence; `robosuite` is installed by the
project's set-up without its dependencies, and never imported: only its MJCF and meshes are read). Each is driven as
the Jaco is: a velocity actuator per joint with the maker's joint speed limit as its range and the maker's peak
torque as its force limit, the bodies gravity-compensated (as the arms' firmware does), and the joint limits of the
model. The wrist camera sits on the flange's tool axis, WRIST_CAMERA_OFFSET_M ahead of it, looking along it: a
small machine-vision camera on the flange (its image size and field of view are the scenario's CameraConfig). The
models' visual meshes (up to 360 000 vertices) would cost software rendering more than the rest of the scene, so
the arms are drawn with their own collision meshes (2–15 000 vertices), coloured as the maker's arms are.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from dm_control import mjcf

from hvs_sim.errors import ConfigError

WRIST_CAMERA_OFFSET_M = 0.04  # the camera's optical centre ahead of the flange, on the tool axis
PEDESTAL_RGBA = [0.3, 0.3, 0.32, 1]
# The velocity loop of a file-read arm, as stiff as the makers' joint velocity controllers: each joint gets ARMATURE
# (kg·m²) and a velocity actuator of gain VELOCITY_GAIN (N·m·s/rad), a time constant of a few ms on the heaviest
# links. The scene's explicit integrator keeps it stable while VELOCITY_GAIN · timestep / ARMATURE < 1 (0.67 at
# 600 Hz); the Jaco keeps dm_control's own (kv 500 on armature 2–4). docs/tuning.md: with Menagerie's armature (0.1)
# and a gain of 40 the loop lagged, and the tracked-corner servo on the Panda ended 0.5–1.3 px off.
ARMATURE = 1.0
VELOCITY_GAIN = 400.0
ROBOSUITE_VERSION = "1.5.2"  # the model files' source, installed by the Makefile (--no-deps)


@dataclass(frozen=True)
class ArmSpec:
    """What an arm is: its name, where its model comes from, and the maker's figures the rig enforces."""

    name: str
    label: str
    source: str  # where the model comes from, with its licence
    reach_m: float  # the maker's figure
    # the base's world position (m), with camera_roll_deg chosen by experiments/arm_placement.py: at the reference
    # camera pose the joints furthest from their limits and the Jacobian furthest from singular
    base: tuple[float, float, float]
    qdot_max: tuple[float, ...] = ()  # rad/s per joint (the maker's); () = the model's own (the Jaco's entity)
    torque_max: tuple[float, ...] = ()  # N·m per joint (the maker's peak)
    folder: str = ""  # robosuite's robots/<folder>
    flange: str = "right_hand"  # the body at the flange; its +Z is the tool axis
    colours: tuple[tuple[float, ...], ...] = ()  # RGBA of the links' collision meshes, base first, cycled
    camera_roll_deg: float = 0.0  # the camera's mount turned about the tool axis (the image's up on the flange)

    @property
    def from_files(self) -> bool:
        """Read from robosuite's model files (ModelArmRig), not built by dm_control (the Jaco)."""
        return bool(self.folder)

    @property
    def dof(self) -> int:
        return len(self.qdot_max) if self.qdot_max else 6


ARMS: dict[str, ArmSpec] = {
    "jaco": ArmSpec("jaco", "Kinova Jaco (6 DOF)", "dm_control's Kinova Jaco entity (Apache-2.0)", 0.90, (0.0, 0.0, 0.9)),
    "panda": ArmSpec(
        "panda", "Franka Emika Panda (7 DOF)", f"robosuite {ROBOSUITE_VERSION} models/assets/robots/panda (MIT)", 0.855,
        (-0.15, 0.0, 0.6), qdot_max=(2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),
        torque_max=(87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0), folder="panda",
        colours=((0.95, 0.95, 0.95, 1), (0.95, 0.95, 0.95, 1), (0.25, 0.25, 0.25, 1)), camera_roll_deg=180.0),
    "ur5e": ArmSpec(
        "ur5e", "Universal Robots UR5e (6 DOF)", f"robosuite {ROBOSUITE_VERSION} models/assets/robots/ur5e (MIT)", 0.85,
        (-0.3, 0.0, 0.75), qdot_max=(np.pi,) * 6, torque_max=(150.0, 150.0, 150.0, 28.0, 28.0, 28.0), folder="ur5e",
        colours=((0.7, 0.7, 0.72, 1), (0.22, 0.45, 0.7, 1))),
    "gen3": ArmSpec(
        "gen3", "Kinova Gen3 (7 DOF)", f"robosuite {ROBOSUITE_VERSION} models/assets/robots/kinova3 (MIT)", 0.902,
        (-0.3, 0.0, 0.9), qdot_max=(1.396, 1.396, 1.396, 1.396, 1.222, 1.222, 1.222),
        torque_max=(39.0, 39.0, 39.0, 39.0, 9.0, 9.0, 9.0), folder="kinova3",
        colours=((0.55, 0.57, 0.6, 1), (0.2, 0.2, 0.22, 1)), camera_roll_deg=180.0),
}
ARM_NAMES: tuple[str, ...] = tuple(ARMS)
DEFAULT_ARM = "jaco"


def robosuite_robots() -> Path:
    """robosuite's robot model folder, found without importing robosuite (its dependencies are not installed)."""
    spec = importlib.util.find_spec("robosuite")
    if spec is None or not spec.submodule_search_locations:
        raise ConfigError(f"the Panda and UR5e models come from robosuite's model files, which are not installed: run "
                          f"`make install` (or `pip install --no-deps robosuite=={ROBOSUITE_VERSION}`)")
    return Path(next(iter(spec.submodule_search_locations))) / "models" / "assets" / "robots"


class ModelArmRig:
    """An arm read from MJCF files (robosuite's), on a pedestal, with velocity actuators and a wrist camera."""

    def __init__(self, root: mjcf.RootElement, spec: ArmSpec, fovy: float):
        path = robosuite_robots() / spec.folder / "robot.xml"
        if not path.is_file():
            raise ConfigError(f"arm model {path} is missing: reinstall robosuite {ROBOSUITE_VERSION} (--no-deps)")
        model = mjcf.from_path(str(path))
        self.spec, self.model = spec, model
        self.joints = [j for j in model.find_all("joint") if j.tag == "joint"]
        if len(self.joints) != spec.dof:
            raise ConfigError(f"{path} has {len(self.joints)} joints, {spec.label} has {spec.dof}")
        _drawn_by_collision_meshes(model, spec.colours)
        for cam in model.find_all("camera"):  # robosuite's own views; the eye is ours
            cam.remove()
        for act in list(model.actuator.all_children()):
            act.remove()
        self.actuators = [model.actuator.add("velocity", name=f"vel_{j.name}", joint=j, kv=VELOCITY_GAIN,
                                             ctrllimited=True, ctrlrange=(-v, v), forcelimited=True,
                                             forcerange=(-t, t))
                          for j, v, t in zip(self.joints, spec.qdot_max, spec.torque_max, strict=True)]
        for j in self.joints:
            j.armature = ARMATURE
        for body in model.find_all("body"):
            body.gravcomp = 1.0
        flange = model.find("body", spec.flange)
        if flange is None:
            raise ConfigError(f"{path} has no body {spec.flange!r} at the flange: the model files are not robosuite "
                              f"{ROBOSUITE_VERSION}'s; reinstall it (--no-deps)")
        # camera frame: the tool axis (+Z) is the optical axis; MuJoCo cameras look along their −Z (180° about X)
        pos = [0.0, 0.0, WRIST_CAMERA_OFFSET_M]
        half = np.radians(spec.camera_roll_deg) / 2
        quat = [0.0, np.cos(half), np.sin(half), 0.0]  # Rz(roll) then 180° about X
        self.camera = flange.add("camera", name="eye", pos=pos, quat=quat, fovy=fovy)
        self.camera_site = flange.add("site", name="eye_site", pos=pos, quat=quat, size=[0.005], group=4)
        x, y, z = spec.base
        root.worldbody.add("geom", name="pedestal", type="cylinder", size=[0.09, z / 2], pos=[x, y, z / 2],
                           rgba=PEDESTAL_RGBA, contype=0, conaffinity=0)
        frame = root.attach(model)
        frame.pos = list(spec.base)

    @property
    def mjcf_model(self):
        return self.model


def check_frame_rate(name: str, fps: float, substeps: int) -> None:
    """A file-read arm's velocity loop is stable while VELOCITY_GAIN · timestep / ARMATURE < 1, the timestep being
    1 / (fps · substeps): refuse a frame rate below that."""
    if not ARMS[name].from_files:
        return
    lowest = VELOCITY_GAIN / ARMATURE / substeps
    if fps <= lowest:
        raise ConfigError(f"{ARMS[name].label}'s velocity loop is unstable below {lowest:.0f} fps (the physics takes "
                          f"{substeps} steps a frame); got fps {fps:g}: give a higher frame rate")


def _drawn_by_collision_meshes(model, colours) -> None:
    """Keep the collision meshes as the drawn arm (no contacts), drop the visual meshes and their files."""
    used = set()
    for k, geom in enumerate(g for g in model.find_all("geom")):
        if geom.group == 1 and geom.contype == 0:  # robosuite's visual geoms
            geom.remove()
            continue
        geom.contype = geom.conaffinity = 0
        geom.group = 0
        geom.material = None
        geom.rgba = list(colours[k % len(colours)]) if colours else [0.8, 0.8, 0.8, 1]
        if geom.mesh is not None:
            used.add(geom.mesh.name)
    for mesh in list(model.asset.find_all("mesh")):
        if mesh.name not in used:
            mesh.remove()
    for material in list(model.asset.find_all("material")):
        material.remove()


def arm_summary(name: str) -> dict:
    """DOF, reach, joint limits (deg) and speed limits (deg/s) of an arm as the scene builds it (hvs-sim scenes)."""
    root = mjcf.RootElement()
    rig = make_arm_rig(root, name, 45.0)
    physics = mjcf.Physics.from_mjcf_model(root)
    j = physics.bind(rig.joints)
    limited = physics.model.jnt_limited[j.element_id].astype(bool)
    lo, hi = np.degrees(np.asarray(j.range, float)).T
    speeds = np.degrees(np.asarray(physics.bind(rig.actuators).ctrlrange, float)[:, 1])
    spec = ARMS[name]
    return {"name": name, "label": spec.label, "dof": len(rig.joints), "reach_m": spec.reach_m, "source": spec.source,
            "joint_limits_deg": [(float(a), float(b)) if lim else None for a, b, lim in zip(lo, hi, limited, strict=True)],
            "speed_limits_deg_s": [float(s) for s in speeds], "base": list(spec.base)}


def make_arm_rig(root: mjcf.RootElement, name: str, fovy: float):
    """The rig of arm `name` (ARMS) in `root`: .joints, .actuators, .camera, .camera_site, .mjcf_model."""
    if name not in ARMS:
        from hvs_sim.errors import choice_error

        raise choice_error("arm", name, ARM_NAMES)
    if not ARMS[name].from_files:
        from hvs_sim.scene.parts import ArmRig

        return ArmRig(root, fovy)
    return ModelArmRig(root, ARMS[name], fovy)

