"""Teach-by-showing: the template from the goal image (`LoopConfig.template_from="goal"`), the tracker seeded in
the first frame (`Tracker.seed`), the template inset from the target's outline, and the scene posed for the capture."""

import json
import math
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from sklearn.datasets import load_sample_image

from hvs_sim.cli import main
from hvs_sim.control.laws.ibvs import IBVSConfig
from hvs_sim.errors import ConfigError, InputError, StateError
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.scene.world import Scene
from hvs_sim.servo.config import GOAL_ROI_INSET_PX, LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.parts import GOAL_FRAMES, NEAR_GOAL_AREA, NEAR_GOAL_SCALE
from hvs_sim.servo.records import summarize_run
from hvs_sim.servo.teach import box_in_view, near_goal_growth
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.frames import inset_roi, roi_corners, roi_from_corners
from hvs_sim.tracking.warp import apply, perspective_transform

H, W = 480, 640
ROI = (250, 170, 120, 84)
SMALL = CameraConfig(width=320, height=240)
TILTED = (0.03, -0.02, 0.06, math.radians(10), math.radians(8), math.radians(-8))


@pytest.fixture(scope="module")
def photo():
    return cv2.resize(load_sample_image("flower.jpg"), (W, H), interpolation=cv2.INTER_AREA)


def _warp_by_corners(shift: np.ndarray) -> np.ndarray:
    src = roi_corners(ROI)
    return perspective_transform(src, src + shift)


@pytest.mark.parametrize("name", ["ecc", "hybrid"])
def test_a_seeded_tracker_aligns_from_the_seed_in_a_frame_other_than_the_templates(photo, name):
    # the template from one image; the next frame a perspective warp of it beyond what a global match without
    # the seed could take (15° of roll): the seed is where alignment starts
    tracker = make_tracker(name, warp="homography")
    tracker.init(photo, ROI)
    c = np.array([ROI[0] + ROI[2] / 2, ROI[1] + ROI[3] / 2])
    R = cv2.getRotationMatrix2D(tuple(c), 15.0, 1.0)
    true = np.vstack([R, [0, 0, 1]]) @ _warp_by_corners(np.array([[3, -2], [-2, 2], [2, 3], [-3, -1.0]]))
    frame = cv2.warpPerspective(photo, true, (W, H), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    seed = true.copy()
    seed[:2, 2] += (1.5, -1.0)  # marked 1–2 px off, as a click would be
    t0 = tracker.seed(seed)
    assert t0.mode == "predict" and np.allclose(t0.corners, apply(seed / seed[2, 2], roi_corners(ROI)))
    tk = tracker.update(frame)
    assert tk.mode == "align"
    assert np.abs(tk.corners - apply(true, roi_corners(ROI))).max() < 0.3


def test_a_similarity_tracker_takes_the_nearest_similarity_and_bad_seeds_are_refused(photo):
    tracker = make_tracker("ecc")
    with pytest.raises(StateError, match="before init"):
        tracker.seed(np.eye(3))
    tracker.init(photo, ROI)
    tracker.seed(_warp_by_corners(np.array([[2, 0], [2, 0], [2, 1], [2, 1.0]])))
    A = tracker.A
    assert np.allclose(A[2], [0, 0, 1]) and np.isclose(A[0, 0], A[1, 1]) and np.isclose(A[0, 1], -A[1, 0])
    behind = np.eye(3)
    behind[2, 0] = -1.0 / ROI[0]  # w ≤ 0 at the template's right-hand corners
    for bad, what in ((np.eye(2), "3×3"), ([[1, 0, 0], [0, 1, 0], [0, 0, np.nan]], "finite"), ("x", "3×3"),
                      (np.zeros((3, 3)) + np.eye(3) * [0, 0, 1], "singular"), (behind, "infinity or behind")):
        with pytest.raises(InputError, match=what):
            tracker.seed(bad)
    for src, dst, what in ((roi_corners(ROI), [[0, 0], [1, 1], [2, 2], [0, 5]], "on a line"),
                           (roi_corners(ROI)[:3], roi_corners(ROI)[:3], "4 finite points")):
        with pytest.raises(InputError, match=what):
            perspective_transform(src, dst)


def test_inset_roi_and_loop_options_are_checked():
    assert inset_roi((10, 20, 100, 60), 8) == (18, 28, 84, 44)
    with pytest.raises(InputError, match="inset by 20 px"):
        inset_roi((10, 20, 100, 60), 20)
    with pytest.raises(ConfigError, match="template_from"):
        LoopConfig(template_from="middle")
    assert inset_roi((100, 120, 100, 60), -30) == (70, 90, 160, 120)  # negative: grown beyond the edges
    for bad in (-401, 2.5, True):
        with pytest.raises(ConfigError, match="roi_inset_px"):
            LoopConfig(roi_inset_px=bad)
    assert main(["bench", "track", "--template-from", "goal"]) == 2
    assert main(["bench", "track", "--roi-inset", "4"]) == 2
    assert main(["bench", "track", "--extra-steps", "40"]) == 2


def test_bench_servo_extra_steps_is_checked(tmp_path):
    assert main(["bench", "servo", "--smoke", "--extra-steps", "40", "--out", str(tmp_path / "a")]) == 2
    assert main(["bench", "servo", "--extra-steps", "-1", "--out", str(tmp_path / "b")]) == 2


def test_posed_scene_puts_the_camera_at_the_reference_and_restores_the_episode():
    scene = Scene(make_scenario("walk_by", mount="arm", camera=SMALL, start_offset=TILTED))
    before = (scene.joint_positions, scene.pose_error(), scene.time)
    with scene.posed(scene.reference_configuration()):
        assert np.abs(scene.pose_error()).max() < 1e-3  # mm and degrees
    assert np.array_equal(scene.joint_positions, before[0]) and np.allclose(scene.pose_error(), before[1])
    assert scene.time == before[2]
    for bad in (np.zeros(3), np.full(6, np.nan), "x"):
        with pytest.raises(InputError, match="joint angles"), scene.posed(bad):
            pass
    handheld = Scene(make_scenario("clear", mount="handheld", camera=SMALL))
    with pytest.raises(ConfigError, match="mount='arm'"), handheld.posed(np.zeros(6)):
        pass


def test_a_renderer_without_people_leaves_them_out_of_the_frame_only():
    scene = Scene(make_scenario("pause", mount="arm", camera=SMALL))
    with_people, without = Renderer(scene), Renderer(scene, people=False)
    for _ in range(scene.scenario.n_frames):  # on to a frame where the person stands in front of the target
        gt = with_people.ground_truth()
        if gt.occlusion > 0.5:
            break
        scene.advance()
    assert gt.occlusion > 0.5
    assert without.ground_truth().occlusion == pytest.approx(gt.occlusion)  # the truth is the scene's
    a, b = with_people.rgb(), without.rgb()
    outline = gt.corners.mean(0).astype(int)
    assert np.abs(a.astype(int) - b).max() > 50 and not np.array_equal(a[outline[1], outline[0]], b[outline[1], outline[0]])


def test_goal_template_loop_servoes_on_the_goal_images_template_seeded_in_the_first_frame():
    sc = make_scenario("clear", mount="arm", start_offset=TILTED)  # 640×480: the target is ~110 px wide at the goal
    cfg = LoopConfig(steps=3, keep_frames=False, template_from="goal", roi_inset_px=4)
    loop = ServoLoop(sc, "hybrid", cfg, warp="homography")
    goal, corners = loop.goal_image()
    roi = inset_roi(roi_from_corners(corners), 4)
    recs = list(loop)
    # s* is the template's own outline in the goal image (the goal image is taken at the reference pose)
    assert np.allclose(recs[0].desired, roi_corners(roi), atol=1e-6)
    assert np.array_equal(loop.tracker.aligner.template_full,
                          cv2.cvtColor(goal, cv2.COLOR_RGB2GRAY)[roi[1]:roi[1] + roi[3], roi[0]:roi[0] + roi[2]])
    # the first frame is aligned (from the seed), 15° of view away from the template
    assert recs[0].mode == "align" and recs[0].tracker_error_px < 0.5, recs[0].tracker_error_px
    assert recs[0].error_px > 20  # and the camera is still far from the goal
    assert all(r.mode == "align" and r.tracker_error_px < 0.5 for r in recs), [(r.mode, r.tracker_error_px) for r in recs]
    s = summarize_run(recs, cfg)
    assert (s["template_from"], s["roi_inset_px"]) == ("goal", 4)


def test_a_negative_inset_grows_the_goal_template_into_the_targets_plane_and_is_refused_where_it_cannot():
    sc = make_scenario("clear", mount="arm", start_offset=TILTED)  # 640×480: the target ~108×72 px at the goal
    cfg = LoopConfig(steps=3, keep_frames=False, template_from="goal", roi_inset_px=-90)
    loop = ServoLoop(sc, "hybrid", cfg, warp="homography")
    _, corners = loop.goal_image()
    box = roi_from_corners(corners)
    roi = (box[0] - 90, box[1] - 90, box[2] + 180, box[3] + 180)  # the neighbouring pictures' edges, in the plane
    recs = list(loop)
    assert np.allclose(recs[0].desired, roi_corners(roi), atol=1e-6)  # s*: the grown box's corners
    assert loop.tracker.aligner.template_full.shape == (roi[3], roi[2])
    # the truth of a corner beyond the target is its place in the target's plane: the tracker meets it
    assert all(r.mode == "align" and r.tracker_error_px < 0.5 for r in recs), [(r.mode, r.tracker_error_px) for r in recs]
    assert summarize_run(recs, cfg)["roi_inset_px"] == -90
    with pytest.raises(ConfigError, match="only a goal template"):  # a start view's surroundings are not the goal's
        ServoLoop(sc, "hybrid", LoopConfig(steps=1, template_from="start", roi_inset_px=-10), warp="homography")
    with pytest.raises(InputError, match="runs off the 640×480 goal image"):
        list(ServoLoop(sc, "hybrid", LoopConfig(steps=1, keep_frames=False, roi_inset_px=-250), warp="homography"))


@pytest.mark.parametrize("pipeline", [False, True])
def test_the_loop_switches_to_the_grown_template_near_the_goal(pipeline):
    # 2 mm off the goal: the default template's corners are within near_goal_px of s* at step 0, so the grown one
    # takes over at step 1, seeded where the small one's corners put it
    sc = make_scenario("clear", mount="arm", start_offset=(0.002, 0.001, 0.0, 0.0, 0.0, 0.0))
    cfg = LoopConfig(steps=4, keep_frames=False, near_goal_inset_px=-90, pipeline=pipeline)
    loop = ServoLoop(sc, "hybrid", cfg, warp="homography")
    _, corners = loop.goal_image()
    box = roi_from_corners(corners)
    small, grown = inset_roi(box, GOAL_ROI_INSET_PX), inset_roi(box, -90)
    recs = list(loop)
    assert [r.template[1] for r in recs] == [GOAL_ROI_INSET_PX, -90, -90, -90]
    assert np.allclose(recs[0].desired, roi_corners(small), atol=1e-6)
    assert all(np.allclose(r.desired, roi_corners(grown), atol=1e-6) for r in recs[1:])  # s*: the grown box's
    assert loop.tracker.aligner.template_full.shape == (grown[3], grown[2])
    # the seed from the small template's corners is good enough for the grown one to align from at once
    assert all(r.mode == "align" and r.tracker_error_px < 0.5 for r in recs), [(r.mode, r.tracker_error_px) for r in recs]
    s = summarize_run(recs, cfg)
    assert s["roi_inset_px"] == GOAL_ROI_INSET_PX and s["near_goal"]["switched_at_step"] == 1
    assert s["near_goal"]["inset_px"] == -90


def test_the_near_goal_template_may_be_tracked_at_a_coarser_working_scale():
    sc = make_scenario("clear", mount="arm", start_offset=(0.002, 0.001, 0.0, 0.0, 0.0, 0.0))
    cfg = LoopConfig(steps=3, keep_frames=False, near_goal_inset_px=-90, near_goal_scale=0.25)
    loop = ServoLoop(sc, "hybrid", cfg, warp="homography")
    first = loop.tracker
    recs = list(loop)
    assert [r.template[1] for r in recs] == [GOAL_ROI_INSET_PX, -90, -90]
    assert loop.tracker is not first and loop.tracker.aligner.config.scale == 0.25 and first.aligner.config.scale == 0.5
    assert loop.tracker.warp == "homography"  # the run's own settings, the scale aside
    assert all(r.mode == "align" and r.tracker_error_px < 0.5 for r in recs), [(r.mode, r.tracker_error_px) for r in recs]
    assert summarize_run(recs, cfg)["near_goal"]["scale"] == 0.25
    for bad in (0, 1.5, True):
        with pytest.raises(ConfigError, match="near_goal_scale"):
            LoopConfig(near_goal_inset_px=-90, near_goal_scale=bad)
    with pytest.raises(ConfigError, match="near_goal_inset_px=None turns off"):
        LoopConfig(near_goal_inset_px=None, near_goal_scale=0.25)


def test_the_near_goal_template_is_refused_where_it_cannot_apply():
    for bad in (0, 5, -401, 2.5, "grown", ""):
        with pytest.raises(ConfigError, match="near_goal_inset_px"):
            LoopConfig(near_goal_inset_px=bad)
    with pytest.raises(ConfigError, match="grows the first one already"):
        LoopConfig(near_goal_inset_px=-90, roi_inset_px=-10)
    with pytest.raises(ConfigError, match="near_goal_inset_px=None turns off"):
        LoopConfig(near_goal_inset_px="off", near_goal_px=3.0)
    with pytest.raises(ConfigError, match="near_goal_px"):
        LoopConfig(near_goal_inset_px=-90, near_goal_px=0.0)
    sc = make_scenario("clear", mount="arm", start_offset=TILTED)
    with pytest.raises(ConfigError, match="comes from its first frame"):
        ServoLoop(sc, "hybrid", LoopConfig(steps=1, template_from="start", near_goal_inset_px=-90), warp="homography")
    with pytest.raises(ConfigError, match="'ground_truth' has no template"):
        ServoLoop(sc, "ground_truth", LoopConfig(steps=1, near_goal_inset_px=-90))
    with pytest.raises(InputError, match="near_goal_inset_px nearer 0"):  # checked at step 0, not at the switch
        list(ServoLoop(sc, "hybrid", LoopConfig(steps=1, keep_frames=False, near_goal_inset_px=-250),
                       warp="homography"))
    assert main(["bench", "track", "--near-goal-inset", "-90"]) == 2
    assert main(["run", "--near-goal-inset", "off", "--near-goal-px", "3", "--steps", "1"]) == 2
    assert main(["run", "--near-goal-inset", "grown", "--steps", "1"]) == 2  # argparse: auto, off or a number
    with pytest.raises(ConfigError, match="depth='true'"):  # IBVS would be given the target's corners' depths
        ServoLoop(sc, "hybrid", LoopConfig(steps=1, near_goal_inset_px=-90, ibvs=IBVSConfig(depth="true")),
                  warp="homography")
    # the servo benchmark refuses a method without a goal template before any episode runs, not in the middle
    from hvs_sim.bench.servo import ServoBenchConfig

    for method in ("ground_truth", "hybrid"):
        with pytest.raises(ConfigError, match=f"servo method '{method}' has no goal template"):
            ServoBenchConfig(trackers=(method, "hybrid:homography"), near_goal_inset_px=-90)
    with pytest.raises(ConfigError, match="a negative --roi-inset"):
        ServoBenchConfig(trackers=("ground_truth",), roi_inset_px=-90)
    ServoBenchConfig(trackers=("hybrid:homography", "hybrid:homography/pbvs"), near_goal_inset_px=-90)


def test_the_automatic_near_goal_template_grows_the_targets_box_to_a_quarter_of_the_image_where_it_has_room():
    cam = SimpleNamespace(width=640, height=480)
    growth, why = near_goal_growth((266, 204, 108, 72), cam)  # the 15 cm target at 0.8 m
    assert why is None and -110 < growth < -80
    area = lambda g: (108 - 2 * g) * (72 - 2 * g) / (640 * 480)
    assert area(growth) <= NEAR_GOAL_AREA < area(growth - 1)  # as far as a quarter of the image, not further
    near_edge, _ = near_goal_growth((60, 204, 108, 72), cam)  # room for 58 px on the left only
    assert growth < -60 < near_edge < -50 and box_in_view(inset_roi((60, 204, 108, 72), near_edge), cam)
    assert near_goal_growth((100, 80, 440, 320), cam)[1].startswith("the target's box already holds 46%")
    assert "no room" in near_goal_growth((5, 204, 108, 72), cam)[1]
    assert LoopConfig(near_goal_inset_px="off").near_goal_inset_px is None


def test_the_loop_switches_to_the_automatic_near_goal_template_by_default_where_it_tracks_a_goal_template():
    sc = make_scenario("clear", mount="arm", start_offset=(0.002, 0.001, 0.0, 0.0, 0.0, 0.0))
    cfg = LoopConfig(steps=3, keep_frames=False)  # the default: NEAR_GOAL_AUTO
    loop = ServoLoop(sc, "hybrid", cfg, warp="homography")
    _, corners = loop.goal_image()
    growth, _ = near_goal_growth(roi_from_corners(corners), sc.camera)
    recs = list(loop)
    assert [r.template[1] for r in recs] == [GOAL_ROI_INSET_PX, growth, growth]
    assert loop.tracker.aligner.config.scale == NEAR_GOAL_SCALE  # the second tracker, at the near-goal scale
    assert all(r.mode == "align" and r.tracker_error_px < 0.5 for r in recs), [(r.mode, r.tracker_error_px) for r in recs]
    plan = loop.near_goal_plan(1)
    assert plan["auto"] and plan["inset_px"] == growth and plan["off"] is None and plan["scale"] == NEAR_GOAL_SCALE
    # where it cannot apply it stays off and says why; a number there is refused (above)
    oracle = ServoLoop(sc, "ground_truth", LoopConfig(steps=1, keep_frames=False))
    list(oracle)
    assert oracle.near_goal_plan(None)["off"] == "tracker 'ground_truth' has no template"
    start = ServoLoop(sc, "hybrid", LoopConfig(steps=1, keep_frames=False, template_from="start"), warp="homography")
    assert start.near_goal_tracker is None and "first frame" in start.resolved.near_goal_off
    assert ServoLoop(sc, "hybrid", LoopConfig(steps=1, near_goal_inset_px=None), warp="homography").near_goal_plan(None) \
        is None
    with pytest.raises(ConfigError, match="near_goal_scale sets the near-goal template, but this run has none"):
        ServoLoop(sc, "ground_truth", LoopConfig(steps=1, near_goal_scale=0.25))


def test_hvs_sim_run_switches_to_the_near_goal_template_by_default(tmp_path):
    out = tmp_path / "run.json"
    assert main(["run", "--warp", "homography", "--start-offset", "0.002,0.001,0,0,0,0", "--steps", "3",
                 "--no-eval", "--json", str(out)]) == 0
    near = json.loads(out.read_text())["near_goal"]
    assert near["auto"] and near["inset_px"] < -80 and near["switched_at_step"] == 1 and near["off"] is None
    assert near["scale"] == NEAR_GOAL_SCALE


def test_the_template_view_and_inset_default_to_the_goal_for_six_dof_tracking_only():
    sc = make_scenario("clear", mount="arm", camera=SMALL, start_offset=TILTED)
    cfg = LoopConfig(steps=1, keep_frames=False)
    assert ServoLoop(sc, "ecc", cfg, warp="homography").template_from == "goal"
    assert ServoLoop(sc, "ecc", cfg).template_from == "start"  # a similarity: 4 DOF, the paper's set-up
    assert ServoLoop(sc, "ground_truth", cfg).template_from == "start"
    # the default inset is GOAL_ROI_INSET_PX, less where the box would fall under MIN_ROI: at 320×240 the target's
    # box in the goal image is 54×36 px, so 6 px keep it at 42×24
    loop = ServoLoop(sc, "ecc", cfg, warp="homography")
    rec = next(iter(loop))
    _, corners = loop.goal_image()
    assert roi_from_corners(corners)[2:] == (54, 36) and rec.template == ("goal", 6, GOAL_FRAMES) and GOAL_ROI_INSET_PX == 8
    big = ServoLoop(make_scenario("clear", mount="arm", start_offset=TILTED), "ecc", cfg, warp="homography")
    assert next(iter(big)).template == ("goal", GOAL_ROI_INSET_PX, GOAL_FRAMES)
    # the oracle's features take no inset, even from the goal image
    oracle = ServoLoop(sc, "ground_truth", LoopConfig(steps=1, keep_frames=False, template_from="goal"))
    assert next(iter(oracle)).template == ("goal", 0, 1)  # the oracle takes only corners from the goal image
