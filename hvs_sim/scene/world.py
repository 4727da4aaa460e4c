"""The simulated world of one scenario: builds the MJCF, owns the physics and moves things in time."""

from __future__ import annotations

import dataclasses
import math
from contextlib import contextmanager

import mujoco
import numpy as np
from dm_control import mjcf

from hvs_sim.errors import ConfigError, InputError
from hvs_sim.geometry import mat_to_quat, mujoco_to_opencv, offset_pose, opencv_to_mujoco, rotation_vector
from hvs_sim.scene.arms import check_frame_rate, make_arm_rig
from hvs_sim.scene.ik import arm_collisions, range_middle, solve_arm_ik, unwound
from hvs_sim.scene.parts import FlagWall, HandheldRig, Person
from hvs_sim.scene.scenarios import Scenario, ShakeModel, occluder_lateral
from hvs_sim.scene.wall import wall_pictures

# Reference camera: 1.3 m high, looking along world +X, upright. Its OpenCV rotation has
# x_cam = −Y_world (right), y_cam = −Z_world (down), z_cam = +X_world (forward).
REFERENCE_POSITION = np.array([0.40, 0.0, 1.30])
IK_CONTINUATION_STEPS = 4  # IK solves from the reference pose to the start pose (stays on the home branch)
IK_RESTARTS, IK_HOME_SEEDS, IK_RESTART_SEED = 24, 24, 7  # seeded IK restarts: start pose when continuation fails, home
WALK_BOB_M, WALK_STEP_HZ = 0.01, 1.0  # a walking person's vertical bob (m) and its rate
ROOM_WALL_BEHIND_M = 0.25  # the room's back wall behind the flag board (m)
REFERENCE_R_CV = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
PHYSICS_SUBSTEPS = 20  # physics steps per frame (timestep = 1 / (fps · substeps))


class Scene:
    """One scenario's world. `reset()` puts everything at t = 0; `advance(qdot)` moves one frame."""

    def __init__(self, scenario: Scenario, framebuffer: tuple[int, int] | None = None):
        """framebuffer: (width, height) of other views rendered beside the eye camera's (the gym env's third-person
        view); the offscreen buffer is made large enough for both."""
        self.scenario = scenario
        cam = scenario.camera
        rng = np.random.default_rng([scenario.seed, 1])
        root = mjcf.RootElement(model="hvs_scene")
        root.option.timestep = 1.0 / (scenario.fps * PHYSICS_SUBSTEPS)
        glob = getattr(root.visual, "global")
        glob.offwidth, glob.offheight = cam.width * cam.supersample, cam.height * cam.supersample
        if framebuffer is not None:
            glob.offwidth, glob.offheight = max(glob.offwidth, framebuffer[0]), max(glob.offheight, framebuffer[1])
        # fixed extent so that clip planes do not depend on where things are: near 1.5 cm, far 30 m
        root.statistic.extent = 3.0
        root.visual.map.znear = 0.005
        root.visual.map.zfar = 10.0
        root.visual.quality.shadowsize = 2048 if scenario.shadows else 0
        root.visual.quality.offsamples = cam.multisample
        root.visual.headlight.ambient = [0.35, 0.35, 0.35]
        root.visual.headlight.diffuse = [0.35, 0.35, 0.35]
        root.visual.headlight.specular = [0.05, 0.05, 0.05]
        root.worldbody.add("light", name="key", pos=[-0.5, 0.6, 2.6], dir=[0.6, -0.25, -0.6],
                           diffuse=[0.55, 0.55, 0.52], castshadow=scenario.shadows)
        floor_tex = root.asset.add("texture", name="floor", type="2d", builtin="checker", width=256, height=256,
                                   rgb1=[0.35, 0.33, 0.3], rgb2=[0.42, 0.4, 0.37])
        floor_mat = root.asset.add("material", name="floor", texture=floor_tex, texrepeat=[8, 8])
        root.asset.add("texture", type="skybox", builtin="gradient", rgb1=[0.75, 0.78, 0.8], rgb2=[0.45, 0.47, 0.5],
                       width=64, height=64)
        room_tex = root.asset.add("texture", name="room", type="2d", builtin="flat", width=128, height=128,
                                  rgb1=[0.72, 0.74, 0.76], mark="random", random=0.01, rgb2=[0.68, 0.7, 0.72])
        room_mat = root.asset.add("material", name="room", texture=room_tex, texrepeat=[6, 3])
        # Geoms are drawn in model order and the software rasteriser shades every fragment that passes the depth
        # test, so the scene is built front to back (people, pictures, board, rig, then the room): the pixels are
        # the same, the overdraw is not (a 640×480 frame 16 → 11 ms on Mesa llvmpipe)
        self.people = [Person(root, i, rng, style=scenario.people) for i in range(len(scenario.occluders))]
        self.wall = FlagWall(root, *wall_pictures(scenario), target_width=scenario.target_width)
        if scenario.mount == "arm":
            check_frame_rate(scenario.arm, scenario.fps, PHYSICS_SUBSTEPS)
            self.rig = make_arm_rig(root, scenario.arm, cam.fovy)
        else:
            self.rig = HandheldRig(root, cam.fovy)
        room = root.worldbody.add("body", name="room")  # static: welded to the world, drawn last
        # the room's back wall, a little behind the flag board
        room.add("geom", name="room_wall", type="box", size=[0.02, 3.0, 1.5],
                 pos=[REFERENCE_POSITION[0] + scenario.standoff + ROOM_WALL_BEHIND_M, 0, 1.5], material=room_mat,
                 contype=0, conaffinity=0)
        room.add("geom", name="floor", type="plane", size=[6, 6, 0.1], material=floor_mat)
        self.camera = self.rig.camera
        self.mjcf_root = root
        self.physics = mjcf.Physics.from_mjcf_model(root)
        self.shake = ShakeModel.sample(scenario.seed, scenario.shake)
        self.target_centre0 = REFERENCE_POSITION + np.array([scenario.standoff, 0.0, 0.0])
        self.reset()

    # ------------------------------------------------------------------ time and kinematics

    @property
    def time(self) -> float:
        return self.frame_index / self.scenario.fps

    @property
    def is_arm(self) -> bool:
        return not isinstance(self.rig, HandheldRig)

    def wall_position(self, t: float) -> np.ndarray:
        ay, az, f = self.scenario.wall_motion
        w = 2 * math.pi * f * t
        return self.target_centre0 + np.array([0.0, ay * math.sin(w), az * (1 - math.cos(w))])

    def reference_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Camera pose (position, OpenCV rotation) that sees the target centred at the standoff."""
        return REFERENCE_POSITION.copy(), REFERENCE_R_CV.copy()

    def start_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference pose displaced by the scenario's start offset (dx, dy, dz, roll, pitch, yaw)."""
        return offset_pose(*self.reference_pose(), self.scenario.start_offset)

    def handheld_pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        pos, R = self.start_pose()
        return offset_pose(pos, R, self.shake.offset(t))

    def camera_position(self) -> np.ndarray:
        return self.physics.bind(self.camera).xpos.copy()

    def camera_pose_cv(self) -> tuple[np.ndarray, np.ndarray]:
        """The camera's world position and OpenCV-convention rotation now (from the simulator)."""
        b = self.physics.bind(self.camera)
        return b.xpos.copy(), mujoco_to_opencv(b.xmat)

    def target_corners_world(self) -> np.ndarray:
        """World positions (4, 3) of the target's front-face corners now: TL, TR, BR, BL as the camera sees them."""
        g = self.physics.bind(self.wall.target)
        return g.xpos + self.wall.corner_offsets() @ g.xmat.reshape(3, 3).T

    def target_center_world(self) -> np.ndarray:
        """World position of the centre of the target's front face now."""
        return self.target_corners_world().mean(axis=0)

    def target_position(self) -> np.ndarray:
        """World position of the target board's centre now (it may move: wall_motion)."""
        return self.physics.bind(self.wall.body).xpos.copy()

    def pose_error(self) -> np.ndarray:
        """The camera's pose error to the reference pose, relative to the target (which may move):
        (x, y, z) in mm and (pitch, yaw, roll) as the rotation vector's components about the
        reference camera's x, y, z in degrees. Truth from the simulator, for evaluation only."""
        pos, R = self.camera_pose_cv()
        ref_pos, ref_R = self.reference_pose()
        d = ref_R.T @ ((pos - self.target_position()) - (ref_pos - self.target_centre0))
        rotvec = rotation_vector(ref_R.T @ R)
        return np.concatenate([1e3 * d, np.degrees(rotvec)])

    def _occluder_line(self, k: int, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Camera and target positions that person k walks across.

        The line follows the camera until the person is about to enter the view (`lock_time`),
        then stays fixed, so the planned occlusion profile holds from any start pose and a
        servoing arm is not chased by the person afterwards.
        """
        plan = self.scenario.occluders[k]
        if k in self._locked_lines:
            return self._locked_lines[k]
        line = (self.camera_position(), self.wall_position(plan.t_cross))
        if t >= plan.lock_time:
            self._locked_lines[k] = line
        return line

    def _place_people(self, t: float) -> None:
        for k, (person, plan) in enumerate(zip(self.people, self.scenario.occluders)):
            c, g = self._occluder_line(k, t)
            line = g - c
            foot = c + plan.depth * line
            horiz = np.array([line[0], line[1], 0.0])
            horiz /= np.linalg.norm(horiz)
            lateral_axis = np.array([-horiz[1], horiz[0], 0.0])
            target_half = self.wall.target_size[0] / 2 * plan.depth
            # walkers pass in profile; a hovering person has stopped and turned to face the camera
            facing = plan.kind == "hover" and t >= plan.t_cross
            lat = occluder_lateral(plan, t, Person.HALF_WIDTH if plan.kind == "hover" else Person.HALF_DEPTH, target_half)
            bob = 0.0 if facing else WALK_BOB_M * abs(math.sin(2 * math.pi * WALK_STEP_HZ * t))
            pos = np.array([foot[0], foot[1], 0.0]) + lateral_axis * lat + np.array([0, 0, bob])
            fwd = -horiz if facing else plan.direction * lateral_axis
            R = np.column_stack([fwd, np.cross([0, 0, 1.0], fwd), [0, 0, 1.0]])
            b = self.physics.bind(person.body)
            b.mocap_pos = pos
            b.mocap_quat = mat_to_quat(R)

    def _apply_time(self) -> None:
        self._apply_kinematics(self.time)

    def _apply_kinematics(self, t: float) -> None:
        """Put everything that moves as a function of time (wall, hand-held camera, people) where it is at t."""
        self.physics.data.time = t
        self.physics.bind(self.wall.body).mocap_pos = self.wall_position(t)
        if not self.is_arm:
            pos, R_cv = self.handheld_pose(t)
            b = self.physics.bind(self.rig.body)
            b.mocap_pos = pos
            b.mocap_quat = mat_to_quat(opencv_to_mujoco(R_cv))
        self.physics.forward()  # camera pose first: the people are placed relative to it
        if self.people:
            self._place_people(t)
            self.physics.forward()

    @contextmanager
    def rewound(self, dt: float):
        """The world as it was dt seconds (at most one frame) before the current frame; restored on exit.

        For a camera's exposure, which ends at the frame time: the kinematic parts follow their time
        functions, the arm's joints are interpolated between the previous and the current frame (a
        joint's velocity barely changes within 1/fps). Physics state is restored exactly, so stepping
        afterwards is unchanged.
        """
        if dt <= 0:
            yield
            return
        with self._restored(("qpos", "mocap_pos", "mocap_quat", "qacc_warmstart")):
            if self.is_arm:
                joints = self.physics.bind(self.rig.joints)
                a = min(1.0, dt * self.scenario.fps)
                joints.qpos = joints.qpos + a * (self._q_prev - joints.qpos)
            self._apply_kinematics(self.time - dt)
            yield

    @contextmanager
    def _restored(self, fields: tuple[str, ...]):
        """Physics data `fields`, the time and the previous frame's joints as they are now, put back on exit."""
        d = self.physics.data
        saved = [(a, getattr(d, a).copy()) for a in fields]
        time_now, q_prev = float(d.time), getattr(self, "_q_prev", None)
        try:
            yield
        finally:
            for name, value in saved:
                getattr(d, name)[:] = value
            d.time, self._q_prev = time_now, q_prev
            self.physics.forward()

    @contextmanager
    def posed(self, q: np.ndarray):
        """The arm held still at joint angles q (at the current time); everything is restored on exit.

        For a still capture away from the episode's state: the goal image a user takes with the camera
        at the reference pose before servoing (`reference_configuration`)."""
        if not self.is_arm:
            raise ConfigError("posing the arm needs mount='arm'")
        n = len(self.rig.joints)
        try:
            q = np.asarray(q, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"q must be {n} joint angles (rad), got {type(q).__name__}") from None
        if q.shape != (n,) or not np.all(np.isfinite(q)):
            raise InputError(f"q must be {n} finite joint angles (rad), got shape {q.shape}")
        with self._restored(("qpos", "qvel", "qacc_warmstart")):
            self.physics.bind(self.rig.joints).qpos = q
            self.physics.bind(self.rig.joints).qvel = 0.0
            self._q_prev = q.copy()  # a blurred capture interpolates towards it: still
            self.physics.forward()
            yield

    def reference_configuration(self) -> np.ndarray:
        """Joint angles that put the camera at the reference pose (the arm's home configuration)."""
        if not self.is_arm:
            raise ConfigError("the reference configuration needs mount='arm'")
        return _home_configuration(self)

    # ------------------------------------------------------------------ arm

    def solve_ik(self, position: np.ndarray, R_cv: np.ndarray, q0: np.ndarray | None = None) -> np.ndarray:
        """Joint angles that put the wrist camera at (position, R_cv); raises ConfigError if unreachable."""
        if not self.is_arm:
            raise ConfigError("inverse kinematics needs mount='arm'")
        return solve_arm_ik(self.mjcf_root, self.physics, self.rig, position, R_cv, q0)

    def camera_jacobian(self) -> np.ndarray:
        """(6, n) world-frame Jacobian [linear; angular] of the camera frame w.r.t. the arm joints."""
        import mujoco

        if not self.is_arm:
            raise ConfigError("the camera Jacobian needs mount='arm'")
        m, d = self.physics.model.ptr, self.physics.data.ptr
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jacSite(m, d, jacp, jacr, self.physics.bind(self.rig.camera_site).element_id)
        dofs = self.physics.bind(self.rig.joints).dofadr
        return np.vstack([jacp[:, dofs], jacr[:, dofs]])

    def joint_limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lower, upper, max velocity) per arm joint; unlimited joints get ±inf."""
        j = self.physics.bind(self.rig.joints)
        limited = j.limited.astype(bool) if hasattr(j, "limited") else self.physics.model.jnt_limited[j.element_id].astype(bool)
        rng = np.asarray(j.range, float)
        lower = np.where(limited, rng[:, 0], -np.inf)
        upper = np.where(limited, rng[:, 1], np.inf)
        qdot_max = np.asarray(self.physics.bind(self.rig.actuators).ctrlrange, float)[:, 1]
        return lower, upper, qdot_max

    def wall_box(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(centre, 3×3 orientation, half sizes) of the picture board, for viewers."""
        g = self.physics.bind(self.wall.body.find("geom", "board"))
        return g.xpos.copy(), g.xmat.reshape(3, 3).copy(), np.array(self.wall.body.find("geom", "board").size, float)

    def _arm_mesh_geoms(self) -> list:
        if not self.is_arm:
            return []
        return [g for g in self.rig.mjcf_model.find_all("geom")
                if int(self.physics.bind(g).type) == mujoco.mjtGeom.mjGEOM_MESH]

    def arm_meshes(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(vertices in the geom frame, triangle indices, RGBA) of each mesh of the arm, for viewers."""
        m, out = self.physics.model, []
        for g in self._arm_mesh_geoms():
            b = self.physics.bind(g)
            k = int(b.dataid)
            v0, nv, f0, nf = m.mesh_vertadr[k], m.mesh_vertnum[k], m.mesh_faceadr[k], m.mesh_facenum[k]
            out.append((np.array(m.mesh_vert[v0:v0 + nv]), np.array(m.mesh_face[f0:f0 + nf]), np.array(b.rgba)))
        return out

    def arm_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """World position (k, 3) and orientation (k, 3, 3) of each arm mesh (arm_meshes' order) now."""
        geoms = self._arm_mesh_geoms()
        if not geoms:
            return np.zeros((0, 3)), np.zeros((0, 3, 3))
        b = self.physics.bind(geoms)
        return np.array(b.xpos, float), np.array(b.xmat, float).reshape(-1, 3, 3)

    def people_poses(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(position of the feet, 3×3 orientation) of each person."""
        return [(self.physics.bind(p.body).xpos.copy(), self.physics.bind(p.body).xmat.reshape(3, 3).copy())
                for p in self.people]

    @property
    def joint_positions(self) -> np.ndarray:
        if not self.is_arm:
            return np.zeros(0)
        return self.physics.bind(self.rig.joints).qpos.copy()

    @property
    def joint_velocities(self) -> np.ndarray:
        if not self.is_arm:
            return np.zeros(0)
        return self.physics.bind(self.rig.joints).qvel.copy()

    def _friction_feedforward(self, cmd: np.ndarray) -> np.ndarray:
        """Velocity offset that cancels joint dry friction, as the Jaco's firmware velocity loop does.

        A velocity actuator makes torque kv·(ctrl − q̇); without this, commands below
        frictionloss / kv (≈ 0.004 rad/s) would not move the joint and servoing would stall.
        """
        m = self.physics.model
        dofs = self.physics.bind(self.rig.joints).dofadr
        kv = self.physics.bind(self.rig.actuators).gainprm[:, 0]
        return m.dof_frictionloss[dofs] / kv * np.tanh(cmd / 1e-3)

    def restart(self, scenario: Scenario) -> None:
        """A new episode of `scenario` on this compiled model and its rendering context: the arm's IK to the new start
        pose and the seed's shake, at a fraction of a new Scene's cost (the gym env's reset). Refused unless
        model_key says a new Scene would build the same model."""
        if model_key(scenario) != model_key(self.scenario):
            raise ConfigError("restart() keeps the compiled model: the new scenario must differ only in its start offset "
                              "(and in its seed where the seed draws nothing of the model); build a new Scene")
        self.scenario = scenario
        self.shake = ShakeModel.sample(scenario.seed, scenario.shake)
        self.reset()

    def reset(self) -> None:
        self.resets = getattr(self, "resets", -1) + 1  # renderers key their per-frame state on (resets, frame)
        self.frame_index = 0
        self._locked_lines: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        if self.is_arm:
            # continuation: walk the IK from the reference pose to the start pose in small steps, so
            # the solution stays on the home branch and every solve starts close to its answer
            q_start = self._start_configuration()
            self.physics.reset()
            self.physics.bind(self.rig.joints).qpos = q_start
            self.physics.bind(self.rig.actuators).ctrl = 0.0
            self._q_prev = q_start.copy()
        self._apply_time()

    def _start_configuration(self) -> np.ndarray:
        """Joint angles of the start pose. Continuation first: the IK walks from the reference pose to
        the start pose in small steps, so the solution stays on the home branch. Where that branch
        runs into a joint limit, a singularity or a collision of the arm (ik.arm_collisions), seeded restarts
        spread over the joint ranges are tried; the collision-free one nearest the home configuration is kept."""
        home = _home_configuration(self)
        ref = self.reference_pose()
        target = offset_pose(*ref, self.scenario.start_offset)
        q = home
        try:
            for alpha in np.linspace(0.0, 1.0, IK_CONTINUATION_STEPS + 1)[1:]:
                q = self.solve_ik(*offset_pose(*ref, alpha * np.asarray(self.scenario.start_offset, float)), q0=q)
            hits = arm_collisions(self.physics, self.rig, q)
            if not hits:
                return q
            first = ConfigError(f"the home branch's configuration collides ({'; '.join(hits)})")
        except ConfigError as exc:
            first = exc
        found = []
        for q0 in _restart_seeds(self, IK_RESTARTS, IK_RESTART_SEED):
            try:
                found.append(self.solve_ik(*target, q0=q0))
            except ConfigError:
                continue
        found = [qs for qs in _off_limits(self, found) if not arm_collisions(self.physics, self.rig, qs)]
        if not found:
            raise ConfigError(f"{first}; the start offset {self.scenario.start_offset_text} cannot be reached by "
                              "the arm without a collision: give a smaller offset")
        return min(found, key=lambda qs: float(np.abs(qs - home).sum()))

    def advance(self, joint_velocity: np.ndarray | None = None) -> None:
        """Move one frame (1/fps s): joint velocity commands for the arm, kinematics for the rest."""
        if self.is_arm:
            self._q_prev = self.joint_positions
            cmd = np.zeros(len(self.rig.actuators)) if joint_velocity is None else np.asarray(joint_velocity, float)
            self.physics.bind(self.rig.actuators).ctrl = cmd + self._friction_feedforward(cmd)
            for _ in range(PHYSICS_SUBSTEPS):
                self.physics.step()
        self.frame_index += 1
        self._apply_time()


def seed_draws_model(scenario: Scenario) -> bool:
    """Whether the scenario's seed draws part of its compiled model: the people's looks, or per-seed textures on the
    wall or as the target (wall_pictures). A flag wall without people is the same model for every seed."""
    textured_target = scenario.target_texture is not None and not scenario.target_image
    textured_wall = scenario.wall != "flags" and not scenario.wall_images
    return bool(scenario.occluders) or textured_target or textured_wall


def model_key(scenario: Scenario) -> Scenario:
    """What a scenario's compiled model is built from: all of it but the start offset, and the seed only where it draws
    part of the model. Two scenarios with one key can share a Scene (Scene.restart)."""
    key = dataclasses.replace(scenario, start_offset=(0.0,) * len(scenario.start_offset))
    return key if seed_draws_model(scenario) else dataclasses.replace(key, seed=0)


def _off_limits(scene: Scene, solutions: list[np.ndarray]) -> list[np.ndarray]:
    """IK restart solutions with each joint that turns more than once on the turn furthest from its limits (unwound
    toward the middle of its range): a restart's seed says nothing about which turn the arm should start on."""
    lower, upper, _ = scene.joint_limits()
    middle = range_middle(lower, upper)
    return [unwound(q, middle, lower, upper) for q in solutions]


def _restart_seeds(scene: Scene, n: int, seed: int) -> list[np.ndarray]:
    """Seeded joint configurations spread over the joints' ranges (±π for unlimited joints)."""
    lower, upper, _ = scene.joint_limits()
    lo, hi = np.where(np.isfinite(lower), lower, -np.pi), np.where(np.isfinite(upper), upper, np.pi)
    rng = np.random.default_rng(seed)
    return [rng.uniform(lo, hi) for _ in range(n)]


def _limit_margin(scene: Scene, q: np.ndarray) -> float:
    lower, upper, _ = scene.joint_limits()
    lim = np.isfinite(lower)
    return float(np.min(np.minimum(q[lim] - lower[lim], upper[lim] - q[lim]))) if lim.any() else np.inf


_HOME: dict[str, np.ndarray] = {}  # per arm: the reference pose is fixed, so its IK solution is solved once


def _home_configuration(scene: Scene) -> np.ndarray:
    """The arm's configuration at the reference pose: of the seeded IK solutions, the one farthest from
    its joint limits, so that start poses all around the reference are reached by continuation from it."""
    if scene.scenario.arm not in _HOME:
        found = []
        for q0 in [np.zeros(len(scene.rig.joints))] + _restart_seeds(scene, IK_HOME_SEEDS, IK_RESTART_SEED):
            try:
                found.append(scene.solve_ik(*scene.reference_pose(), q0=q0))
            except ConfigError:
                continue
        if not found:
            raise ConfigError("the arm cannot reach the reference camera pose (no IK solution from any seed)")
        _HOME[scene.scenario.arm] = max(_off_limits(scene, found), key=lambda q: _limit_margin(scene, q))
    return _HOME[scene.scenario.arm].copy()
