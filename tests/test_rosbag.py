"""`run --mcap`: a run as a ROS 2 bag (MCAP) that ROS tools read (hvs_sim/viz/rosbag.py), read back with rosbags."""

import numpy as np
import pytest

from hvs_sim.runner import run_episode
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.viz.rosbag import TOPICS

SMALL = CameraConfig(width=160, height=120)
STEPS = 6


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("bag") / "run_bag"
    _, records = run_episode(make_scenario("walk_by", mount="arm", camera=SMALL), "ground_truth",
                             LoopConfig(steps=STEPS, keep_frames=True), mcap=str(out), progress=False,
                             keep_records=True)
    from rosbags.highlevel import AnyReader

    messages: dict[str, list] = {}
    with AnyReader([out]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for conn, ns, raw in reader.messages():
            messages.setdefault(conn.topic, []).append((ns, reader.deserialize(raw, conn.msgtype)))
    return out, records, types, messages


def test_every_topic_with_its_type_and_one_message_a_step(bag):
    out, records, types, messages = bag
    assert (out / "metadata.yaml").is_file() and [p.name for p in out.glob("*.mcap")] == ["run_bag.mcap"]
    assert types == TOPICS
    for topic in TOPICS:
        assert len(messages[topic]) == (1 if topic == "/tf_static" else STEPS), topic
    stamps = [ns for ns, _ in messages["/cmd_twist"]]
    assert stamps == [round(r.time * 1e9) for r in records]  # the simulation clock


def test_the_values_are_the_runs(bag):
    import cv2

    _, records, _, messages = bag
    info = messages["/camera/camera_info"][0][1]
    assert (info.width, info.height) == (160, 120) and info.k[0] > 0 and info.k[2] == pytest.approx(79.5, abs=1)
    for (_, twist), r in zip(messages["/cmd_twist"], records, strict=True):
        got = [twist.twist.linear.x, twist.twist.linear.y, twist.twist.linear.z,
               twist.twist.angular.x, twist.twist.angular.y, twist.twist.angular.z]
        assert np.allclose(got, r.twist)
    for (_, tf), r in zip(messages["/tf"], records, strict=True):
        tr = tf.transforms[0]
        assert (tf.transforms[0].header.frame_id, tr.child_frame_id) == ("world", "camera_optical")
        assert np.allclose([tr.transform.translation.x, tr.transform.translation.y, tr.transform.translation.z],
                           r.camera.t)
    for (_, poly), r in zip(messages["/corners/true"], records, strict=True):
        assert np.allclose([[p.x, p.y] for p in poly.polygon.points], r.gt_features, atol=1e-4)
    joints = messages["/joint_states"][-1][1]
    assert len(joints.name) == len(records[-1].q) and np.allclose(joints.position, records[-1].q)
    jpeg = messages["/camera/image/compressed"][0][1]
    frame = cv2.imdecode(np.asarray(jpeg.data, np.uint8), cv2.IMREAD_COLOR)
    assert jpeg.format == "jpeg" and frame.shape == (120, 160, 3)


def test_cli_refuses_an_existing_bag_folder(tmp_path, capsys):
    from hvs_sim.cli import main

    (tmp_path / "bag").mkdir()
    assert main(["run", "--steps", "2", "--mcap", str(tmp_path / "bag")]) == 2
    assert "a ROS 2 bag is a new folder" in capsys.readouterr().err


def test_track_writes_the_frames_and_the_tracked_corners_as_a_bag(tmp_path):
    import cv2
    from rosbags.highlevel import AnyReader

    from hvs_sim.cli import main
    from hvs_sim.viz.rosbag import TRACK_TOPICS

    folder = tmp_path / "clip"
    folder.mkdir()
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.integers(0, 255, (120, 160, 3), np.uint8), (0, 0), 1.5)
    for k in range(5):
        cv2.imwrite(str(folder / f"f{k}.png"), np.roll(img, k, axis=1))
    bag = tmp_path / "track_bag"
    assert main(["track", str(folder), "--roi", "50,40,48,40", "--tracker", "ecc", "--out", str(tmp_path / "out"),
                 "--mcap", str(bag)]) == 0
    with AnyReader([bag]) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == TRACK_TOPICS
        got = {}
        for conn, ns, raw in reader.messages():
            got.setdefault(conn.topic, []).append((ns, reader.deserialize(raw, conn.msgtype)))
    assert all(len(v) == 5 for v in got.values())
    rows = (tmp_path / "out" / "track.csv").read_text().splitlines()[1:]
    for (ns, poly), row in zip(got["/corners/tracked"], rows, strict=True):
        frame, cx, cy = row.split(",")[:3]
        assert ns == round(int(frame) / 30 * 1e9)  # a folder plays at 30 fps
        centre = np.mean([[p.x, p.y] for p in poly.polygon.points], axis=0)
        assert np.allclose(centre, [float(cx), float(cy)], atol=0.05)  # the corners of the CSV's centre
    assert got["/track/mode"][0][1].data == "init"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip", "out", "track_bag"]  # no temporary left


def test_scene_writes_its_frames_and_truth_as_a_bag_with_the_lens(tmp_path):
    from rosbags.highlevel import AnyReader

    from hvs_sim.cli import main
    from hvs_sim.viz.rosbag import SCENE_TOPICS

    bag = tmp_path / "scene_bag"
    assert main(["scene", "--scenario", "walk_by", "--mount", "arm", "--frames", "4", "--width", "160", "--height",
                 "120", "--camera", "webcam", "--out", str(tmp_path / "out"), "--mcap", str(bag)]) == 0
    with AnyReader([bag]) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == SCENE_TOPICS
        got = {}
        for conn, ns, raw in reader.messages():
            got.setdefault(conn.topic, []).append((ns, reader.deserialize(raw, conn.msgtype)))
    assert all(len(v) == 4 for v in got.values()) and [p.name for p in bag.glob("*.mcap")] == ["scene_bag.mcap"]
    truth = np.load(tmp_path / "out" / "ground_truth.npz")
    for k, (ns, poly) in enumerate(got["/corners/true"]):
        assert abs(ns - truth["time"][k] * 1e9) < 1e3  # the CSV and NPZ keep the time to the microsecond
        assert np.allclose([[p.x, p.y] for p in poly.polygon.points], truth["corners"][k], atol=1e-4)
    info = got["/camera/camera_info"][0][1]
    from hvs_sim.sensor import sensor_preset

    lens = sensor_preset("webcam").distortion
    assert np.allclose(info.d[:len(lens)], lens) and np.allclose(np.reshape(info.k, (3, 3)), truth["K"])
    tf = got["/tf"][0][1].transforms
    assert [t.child_frame_id for t in tf] == ["camera_optical", "target"]
    cam = tf[0].transform.translation
    assert np.allclose([cam.x, cam.y, cam.z], truth["camera_pose"][0][:3, 3])
    names = got["/joint_states"][0][1].name
    assert len(names) == 6 and np.allclose(got["/joint_states"][0][1].position, truth["joint_positions"][0])
    assert 0 <= got["/target/occlusion"][0][1].data <= 1
    tgt = tf[1].transform.translation  # the target's centre, about a standoff (0.8 m) from the camera
    assert 0.6 < np.linalg.norm(np.subtract([tgt.x, tgt.y, tgt.z], [cam.x, cam.y, cam.z])) < 1.0
