"""A closed-loop run as a ROS 2 bag in MCAP format: what robotics users open in Foxglove, rviz (through `ros2 bag
play`) or plot with their own ROS tools. Written by `rosbags` (pure Python, no ROS install), ROS 2 Humble types.

Topics, every message stamped with the simulation time of its step (`StepRecord.time`):

| topic | type | what |
|---|---|---|
| `/camera/image/compressed` | sensor_msgs/CompressedImage | the camera's frame (JPEG), frame `camera_optical` |
| `/camera/camera_info` | sensor_msgs/CameraInfo | K, the image size and the lens's distortion (plumb-bob: OpenCV's k1, k2, p1, p2, k3; zeros without one) |
| `/joint_states` | sensor_msgs/JointState | the arm's joint angles and velocities (none for a hand-held camera) |
| `/tf` | tf2_msgs/TFMessage | world → camera_optical (OpenCV axes: x right, y down, z forward) |
| `/tf_static` | tf2_msgs/TFMessage | world → target (the target's centre; x along its top edge, y down its left edge) |
| `/cmd_twist` | geometry_msgs/TwistStamped | the commanded camera twist, in camera_optical |
| `/corners/tracked`, `/corners/true`, `/corners/desired` | geometry_msgs/PolygonStamped | the four corners in image pixels (x, y, 0), frame `camera_image` |

`hvs-sim scene --mcap` (SceneBag) writes the image, camera_info, joint_states (arm mount; positions), `/tf` with
world → camera_optical and world → target at every frame (the wall may move), `/corners/true` and `/target/occlusion`
(std_msgs/Float32, the share of the target hidden). `hvs-sim track --mcap` (FootageBag): image, `/corners/tracked`
and `/track/mode` (std_msgs/String).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hvs_sim.sensor import encode_jpeg

WORLD, CAMERA, TARGET, IMAGE = "world", "camera_optical", "target", "camera_image"
JPEG_QUALITY = 90
TOPICS = {
    "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/camera/camera_info": "sensor_msgs/msg/CameraInfo",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/cmd_twist": "geometry_msgs/msg/TwistStamped",
    "/corners/tracked": "geometry_msgs/msg/PolygonStamped",
    "/corners/true": "geometry_msgs/msg/PolygonStamped",
    "/corners/desired": "geometry_msgs/msg/PolygonStamped",
}


def target_frame(corners_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the target in the world from its four corners (top-left, top-right, bottom-right, bottom-left)."""
    c = np.asarray(corners_world, float)
    x = c[1] - c[0]
    x /= np.linalg.norm(x)
    y = c[3] - c[0]
    y -= x * (x @ y)
    y /= np.linalg.norm(y)
    return np.column_stack([x, y, np.cross(x, y)]), c.mean(axis=0)


# `hvs-sim scene --mcap`: an open-loop render with its truth; no command, no tracker
SCENE_TOPICS = {
    "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/camera/camera_info": "sensor_msgs/msg/CameraInfo",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/corners/true": "geometry_msgs/msg/PolygonStamped",
    "/target/occlusion": "std_msgs/msg/Float32",
}

# `hvs-sim track --mcap`: footage has no K, joints or twist; the tracker's mode as text
TRACK_TOPICS = {
    "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/corners/tracked": "geometry_msgs/msg/PolygonStamped",
    "/track/mode": "std_msgs/msg/String",
}


class _Bag:
    """A new bag folder `path` (rosbags refuses an existing one) with one connection per topic. `close()` finishes
    the bag's index and metadata; a bag not closed is not readable, so callers write it under a temporary name and
    give the folder's final name as `name`: the MCAP file inside, which rosbags names after the folder, is renamed
    after it on close (a hidden temporary-looking file is what a user would otherwise open in Foxglove)."""

    def __init__(self, path: Path, topics: dict[str, str], name: str | None = None):
        self.path, self.name = Path(path), name
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore

        self.store = get_typestore(Stores.ROS2_HUMBLE)
        self.t = self.store.types
        self.topics = topics
        self.writer = Writer(Path(path), version=8, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.conn = {topic: self.writer.add_connection(topic, msgtype, typestore=self.store)
                     for topic, msgtype in topics.items()}
        self.count = dict.fromkeys(topics, 0)

    def _write(self, topic: str, msg, ns: int) -> None:
        from hvs_sim import outputs

        data = self.store.serialize_cdr(msg, self.topics[topic])
        try:
            outputs.ensure_space(self.path / "bag.mcap", len(data), native=False)
            self.writer.write(self.conn[topic], ns, data)
        except OSError as exc:  # a full disk: the bag is named by the folder the user gave
            if isinstance(exc, outputs.OutputError):
                raise
            raise outputs.output_error(self.path.with_name(self.name or self.path.name), exc) from None
        self.count[topic] += 1

    def _header(self, seconds: float, frame: str):
        ns = round(seconds * 1e9)
        stamp = self.t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        return self.t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame), ns

    def _transform(self, header, child: str, R: np.ndarray, t: np.ndarray):
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_matrix(R).as_quat()
        tr = self.t["geometry_msgs/msg/Transform"](
            translation=self.t["geometry_msgs/msg/Vector3"](x=float(t[0]), y=float(t[1]), z=float(t[2])),
            rotation=self.t["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w)))
        return self.t["geometry_msgs/msg/TransformStamped"](header=header, child_frame_id=child, transform=tr)

    def _polygon(self, header, corners: np.ndarray):
        pts = [self.t["geometry_msgs/msg/Point32"](x=float(u), y=float(v), z=0.0)
               for u, v in np.nan_to_num(np.asarray(corners, float), nan=-1.0)]  # NaN (no estimate): off-image
        return self.t["geometry_msgs/msg/PolygonStamped"](header=header, polygon=self.t["geometry_msgs/msg/Polygon"](
            points=pts))

    def _image(self, header, ns: int, frame: np.ndarray) -> None:
        data = np.frombuffer(encode_jpeg(frame, JPEG_QUALITY).tobytes(), np.uint8)
        self._write("/camera/image/compressed",
                    self.t["sensor_msgs/msg/CompressedImage"](header=header, format="jpeg", data=data), ns)

    def _camera_info(self, header, K: np.ndarray, size: tuple[int, int], distortion=()):
        w, h = size
        P = np.zeros((3, 4))
        P[:, :3] = K
        d = np.zeros(5)
        d[:len(distortion)] = distortion  # OpenCV's (k1, k2, p1, p2[, k3]), ROS's plumb_bob order
        roi = self.t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
        return self.t["sensor_msgs/msg/CameraInfo"](
            header=header, height=h, width=w, distortion_model="plumb_bob", d=d, k=np.asarray(K, float).ravel().copy(),
            r=np.eye(3).ravel(), p=P.ravel(), binning_x=0, binning_y=0, roi=roi)

    def _joint_state(self, seconds: float, names, q, qdot=None):
        header, _ = self._header(seconds, "")
        return self.t["sensor_msgs/msg/JointState"](
            header=header, name=list(names), position=np.asarray(q, float),
            velocity=np.zeros(0) if qdot is None else np.asarray(qdot, float), effort=np.zeros(0))

    def close(self) -> None:
        from hvs_sim import outputs

        try:
            self.writer.close()
        except OSError as exc:
            raise outputs.output_error(self.path.with_name(self.name or self.path.name), exc) from None
        if self.name and self.name != self.path.name:
            old, new = f"{self.path.name}.mcap", f"{self.name}.mcap"
            (self.path / old).rename(self.path / new)
            meta = self.path / "metadata.yaml"
            meta.write_text(meta.read_text().replace(old, new))


class SceneBag(_Bag):
    """`hvs-sim scene --mcap`: each frame of an open-loop render with its truth (module docstring)."""

    def __init__(self, path: Path, K: np.ndarray, width: int, height: int, distortion=(), name: str | None = None):
        super().__init__(path, SCENE_TOPICS, name)
        self.K, self.size, self.distortion = np.asarray(K, float), (int(width), int(height)), tuple(distortion)
        self.joint_names: list[str] = []

    def start(self, scene) -> None:
        """The scene once built: the arm's joint names (none for a hand-held camera)."""
        if scene.is_arm:
            self.joint_names = [j.name for j in scene.rig.joints]

    def log(self, frame: np.ndarray, gt) -> None:
        """One frame and its GroundTruth."""
        t = self.t
        cam_header, ns = self._header(gt.time, CAMERA)
        self._image(cam_header, ns, frame)
        self._write("/camera/camera_info", self._camera_info(cam_header, self.K, self.size, self.distortion), ns)
        if self.joint_names:
            self._write("/joint_states", self._joint_state(gt.time, self.joint_names, gt.joint_positions), ns)
        world, _ = self._header(gt.time, WORLD)
        transforms = [self._transform(world, CAMERA, gt.camera.R, gt.camera.t),
                      self._transform(world, TARGET, *target_frame(gt.target_world))]
        self._write("/tf", t["tf2_msgs/msg/TFMessage"](transforms=transforms), ns)
        image, _ = self._header(gt.time, IMAGE)
        self._write("/corners/true", self._polygon(image, gt.corners), ns)
        self._write("/target/occlusion", t["std_msgs/msg/Float32"](data=float(np.nan_to_num(gt.occlusion))), ns)


class FootageBag(_Bag):
    """`hvs-sim track --mcap`: each frame (JPEG), the tracked corners and the mode, stamped at frame / fps."""

    def __init__(self, path: Path, fps: float, name: str | None = None):
        super().__init__(path, TRACK_TOPICS, name)
        self.fps = float(fps)

    def log(self, index: int, frame: np.ndarray, corners: np.ndarray, mode: str) -> None:
        header, ns = self._header(index / self.fps, CAMERA)
        self._image(header, ns, frame)
        image, _ = self._header(index / self.fps, IMAGE)
        self._write("/corners/tracked", self._polygon(image, corners), ns)
        self._write("/track/mode", self.t["std_msgs/msg/String"](data=str(mode)), ns)


class BagRecorder(_Bag):
    """`hvs-sim run --mcap`: a run's steps (module docstring)."""

    def __init__(self, path: Path, K: np.ndarray, width: int, height: int, joint_names=(),
                 target: tuple[np.ndarray, np.ndarray] | None = None, distortion=(), name: str | None = None):
        super().__init__(path, TOPICS, name)
        self.K, self.size, self.joint_names = np.asarray(K, float), (int(width), int(height)), list(joint_names)
        self.target, self.distortion = target, tuple(distortion)

    def log_step(self, r) -> None:
        """One StepRecord (its frame, when the loop kept it)."""
        t = self.t
        cam_header, ns = self._header(r.time, CAMERA)
        if self.count["/tf_static"] == 0 and self.target is not None:
            world, _ = self._header(r.time, WORLD)
            self._write("/tf_static", t["tf2_msgs/msg/TFMessage"](transforms=[self._transform(world, TARGET,
                                                                                               *self.target)]), ns)
        if r.frame is not None:
            self._image(cam_header, ns, r.frame)
        self._write("/camera/camera_info", self._camera_info(cam_header, self.K, self.size, self.distortion), ns)
        if self.joint_names:
            self._write("/joint_states", self._joint_state(r.time, self.joint_names, r.q, r.qdot), ns)
        world, _ = self._header(r.time, WORLD)
        self._write("/tf", t["tf2_msgs/msg/TFMessage"](transforms=[self._transform(world, CAMERA, r.camera.R,
                                                                                   r.camera.t)]), ns)
        v = np.nan_to_num(np.asarray(r.twist, float))
        twist = t["geometry_msgs/msg/Twist"](linear=t["geometry_msgs/msg/Vector3"](x=v[0], y=v[1], z=v[2]),
                                             angular=t["geometry_msgs/msg/Vector3"](x=v[3], y=v[4], z=v[5]))
        self._write("/cmd_twist", t["geometry_msgs/msg/TwistStamped"](header=cam_header, twist=twist), ns)
        image, _ = self._header(r.time, IMAGE)
        for topic, corners in (("/corners/tracked", r.features), ("/corners/true", r.gt_features),
                               ("/corners/desired", r.desired)):
            self._write(topic, self._polygon(image, corners), ns)
