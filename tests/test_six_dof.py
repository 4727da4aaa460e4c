"""Full 6-DOF servoing: homography LK, projective warps, 6-DOF IBVS, PBVS, pose-error truth, start poses."""

import json
import math

import cv2
import numpy as np
import pytest
from photos import photo

from hvs_sim.cli import main
from hvs_sim.control.laws.ibvs import DOF_NAMES, SIMILARITY_DOFS, IBVSConfig, IBVSController
from hvs_sim.control.laws.pbvs import PBVSController
from hvs_sim.errors import ConfigError
from hvs_sim.geometry import offset_pose
from hvs_sim.render.camera import intrinsics
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.servo.config import LoopConfig
from hvs_sim.servo.loop import ServoLoop
from hvs_sim.servo.records import summarize_run
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.feature_lk import sample_points
from hvs_sim.tracking.frames import roi_corners, roi_from_corners
from hvs_sim.tracking.warp import apply, homography_params_to_matrix, local_affine, matrix_to_pose

H, W = 480, 640
ROI = (250, 170, 120, 84)
SMALL = CameraConfig(width=320, height=240)
TILTED = (0.03, -0.02, 0.06, math.radians(10), math.radians(8), math.radians(-8))  # the start pose




def perspective(shift: np.ndarray) -> np.ndarray:
    """The homography that moves the ROI's corners by `shift` (4×2 px)."""
    src = roi_corners(ROI).astype(np.float32)
    return cv2.getPerspectiveTransform(src, (src + shift).astype(np.float32))


def corner_errors(tracker, name, amplitude=4.0, n=4):
    img = photo(name)
    tracker.init(img, ROI)
    out = []
    for k in range(n):
        Hm = perspective(np.random.default_rng(k).uniform(-amplitude, amplitude, (4, 2)))
        frame = cv2.warpPerspective(img, Hm, (W, H), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
        tracker.A = np.eye(3)
        tk = tracker.update(frame)
        assert tk.mode == "align"
        true = cv2.perspectiveTransform(roi_corners(ROI)[None].astype(np.float64), Hm)[0]
        out.append(np.linalg.norm(tk.corners - true, axis=1).max())
    return np.array(out)


@pytest.fixture(scope="module")
def homography_lk():
    return make_tracker("deep_lk", warp="homography")


@pytest.mark.parametrize("name", ["china", "flower"])
def test_homography_tracker_recovers_perspective_warps_of_photos(homography_lk, name):
    # feature LK (half resolution), then the intensity refinement on the full-resolution grey template
    # (intensity_ic.py): the target, every corner within 0.1 px (with ECC instead: 0.3 / 0.2 px held)
    err = corner_errors(homography_lk, name)
    assert err.max() < 0.1, err


def test_hybrid_gates_occlusion_where_it_aligned_not_at_a_misaligned_seed():
    # a sharp photo 4 px out of perspective: OP_t at the unaligned seed reads 0.41, over the 0.4 gate, though nothing
    # covers it; the paper's rule (gate at the seed) predicts, and stays 4.7 px off
    from sklearn.datasets import load_sample_image

    img = cv2.resize(load_sample_image("flower.jpg"), (W, H), interpolation=cv2.INTER_AREA)
    Hm = perspective(np.random.default_rng([5, 3]).uniform(-4, 4, (4, 2)))
    frame = cv2.warpPerspective(img, Hm, (W, H), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    true = cv2.perspectiveTransform(roi_corners(ROI)[None].astype(np.float64), Hm)[0]
    seed_gate, hybrid = make_tracker("hybrid_seed_gate", warp="homography"), make_tracker("hybrid", warp="homography")
    assert hybrid.hconfig.gate_after_alignment and not make_tracker("hybrid_paper").hconfig.gate_after_alignment
    for tracker in (seed_gate, hybrid):
        tracker.init(img, ROI)
    tk = seed_gate.update(frame)
    assert tk.mode == "predict" and tk.occlusion >= hybrid.hconfig.occlusion_gate
    tk = hybrid.update(frame)
    assert tk.mode == "align" and tk.occlusion < 0.05  # OP_t where it aligned
    assert np.linalg.norm(tk.corners - true, axis=1).max() < 0.1
    # a board over 55 % of the target: the match stays confident, so the frame is aligned (LK ran), and OP_t there
    # refuses it
    covered = frame.copy()
    x, y, w, h = ROI
    covered[y - 10:y + h + 10, x - 10:x + int(0.55 * w)] = (90, 120, 60)
    hybrid.seed(np.eye(3))
    tk = hybrid.update(covered)
    assert tk.score >= hybrid.config.match_threshold and "lk" in hybrid.stage_ms
    assert tk.mode != "align" and tk.occlusion >= hybrid.hconfig.occlusion_gate
    # a far re-acquisition through a seed that fails the gate is confirmed after reacquire_frames frames, as any other:
    # the seed made to read as hidden (the first OP_t of each frame is the seed's), the estimate 30 px off. Without the
    # context check: with it, the target's own ring of picture agrees there and not at the estimate, and it is taken
    # at once (tests/test_evidence.py)
    at_once = make_tracker("hybrid", warp="homography")
    at_once.init(img, ROI)
    at_once.seed(np.array([[1.0, 0, 30.0], [0, 1, 0], [0, 0, 1]]))
    assert at_once.update(frame).mode == "align"
    far = make_tracker("hybrid", warp="homography", context_check=False)
    far.init(img, ROI)
    far.seed(np.array([[1.0, 0, 30.0], [0, 1, 0], [0, 0, 1]]))
    calls, measured = [], far._occlusion_at

    def seed_reads_hidden(frame, A, grey):
        calls.append(A)
        return max(measured(frame, A, grey), 0.5) if len(calls) == 1 else measured(frame, A, grey)

    far._occlusion_at = seed_reads_hidden
    modes = []
    for _ in range(far.hconfig.reacquire_frames):
        calls.clear()
        modes.append(far.update(frame).mode)
        assert len(calls) >= 2  # gated again where it aligned (and where the surroundings put it)
    assert modes == ["predict"] * (far.hconfig.reacquire_frames - 1) + ["align"], modes
    assert np.linalg.norm(far.update(frame).corners - true, axis=1).max() < 0.1


def test_similarity_tracker_cannot_follow_a_perspective_warp():
    # the reason for the homography: a similarity leaves corners of a tilted target pixels off
    err = corner_errors(make_tracker("deep_lk"), "flower")
    assert err.max() > 1.0, err


def test_homography_steepest_descent_matches_finite_differences(homography_lk):
    homography_lk.init(photo("china"), ROI)
    lk = homography_lk.aligner.lk_engine
    assert lk.n_params == 8
    for level in lk.levels:
        fmap = lk.template_maps[level.name]
        sd = level.sd.view(-1, fmap.shape[0], 8).numpy()
        for i in range(8):
            dp = np.zeros(8)
            dp[i] = 1e-4
            plus = sample_points(fmap, lk.to_work(homography_params_to_matrix(dp), level.pts), lk.template_origin, level.stride)[0]
            minus = sample_points(fmap, lk.to_work(homography_params_to_matrix(-dp), level.pts), lk.template_origin,
                                  level.stride)[0]
            fd = ((plus - minus) / 2e-4).double().numpy()
            rel = np.linalg.norm(fd - sd[:, :, i]) / np.linalg.norm(sd[:, :, i])
            assert rel < 2e-2, (level.name, i, rel)


def test_projective_apply_and_local_pose():
    Hm = np.array([[1.02, 0.01, 3.0], [-0.02, 0.98, -2.0], [2e-4, -1e-4, 1.0]])
    pts = np.array([[10.0, 20.0], [300.0, 40.0]])
    ref = cv2.perspectiveTransform(pts[None], Hm)[0]
    assert np.allclose(apply(Hm, pts), ref)
    c = np.array([150.0, 100.0])
    # the local affine map agrees with the homography to first order at the centre
    d = np.array([0.01, -0.02])
    lin = apply(local_affine(Hm, c), (c + d)[None])[0]
    assert np.allclose(lin, apply(Hm, (c + d)[None])[0], atol=1e-6)
    assert np.allclose(matrix_to_pose(Hm, c)[:2], apply(Hm, c[None])[0] - c)
    # a centre on the horizon has no local affine map: a non-finite answer, not an exception
    horizon = np.array([[1.0, 0, 0], [0, 1.0, 0], [-0.1, 0, 1.0]])  # w = 0 at x = 10
    assert not np.all(np.isfinite(local_affine(horizon, (10.0, 0.0))))
    assert not np.all(np.isfinite(matrix_to_pose(horizon, (10.0, 0.0))))
    # the homography LK's update size: the largest corner move of the unit box, infinite where a corner goes to infinity
    from hvs_sim.tracking.feature_lk import FeatureICLK, LKConfig

    lk = FeatureICLK(LKConfig(), warp="homography")
    lk.rho = 30.0
    dp = np.array([0.01, 0, 0.02, 0, -0.01, 0, 1e-3, 0])
    box = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    assert lk.update_size(dp) == pytest.approx(30.0 * np.abs(apply(homography_params_to_matrix(dp), box) - box).max())
    assert lk.update_size(np.array([0, 0, 0, 0, 0, 0, -1.0, 0])) == math.inf


def test_residual_and_unknown_warp_are_refused():
    with pytest.raises(ConfigError, match="similarity correction"):
        make_tracker("deep_lk", warp="homography", residual=True)
    with pytest.raises(ConfigError, match="warp"):
        make_tracker("hybrid", warp="affine")
    with pytest.raises(ConfigError, match="warp"):
        make_tracker("ecc", warp="projective")


def test_roi_of_a_target_rolled_far_is_a_box_inside_it():
    c, half = np.array([400.0, 300.0]), np.array([60.0, 40.0])
    a = math.radians(54)
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    quad = c + (half * [[-1, -1], [1, -1], [1, 1], [-1, 1]]) @ R.T
    x, y, w, h = roi_from_corners(quad)
    assert w >= 30 and h >= 30  # the inner-edge box would be a sliver
    box = np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]], float)
    rel = (box - c) @ R  # in the target's own axes
    assert np.all(np.abs(rel) <= half + 1.0)


def test_ibvs_reports_rank_and_condition_and_commands_six_dofs_when_asked():
    K = intrinsics(640, 480, 45)
    desired = np.array([[260.0, 200], [380, 200], [380, 280], [260, 280]])
    six = IBVSController(K, desired, 0.8, dofs=DOF_NAMES).compute(desired + [[1, 0], [0, 1], [2, 1], [0, 0]])
    assert six.rank == 6 and 1 < six.condition < 1e4
    assert np.any(six.twist[3:5] != 0)
    four = IBVSController(K, desired, 0.8).compute(desired + 1.0)  # default: a similarity tracker's 4 DOFs
    assert four.rank == 4 and four.twist[3] == 0 and four.twist[4] == 0


def test_pbvs_commands_the_camera_straight_to_the_goal():
    K = intrinsics(640, 480, 45)
    Z = 0.8
    desired = np.array([[260.0, 200], [380, 200], [380, 280], [260, 280]])
    ctl = PBVSController(K, desired, Z, IBVSConfig(gain=1.0, max_linear=10, max_angular=10), dofs=DOF_NAMES)
    # the camera displaced by d (its own frame, no rotation): the model points move by −d
    d = np.array([0.02, -0.01, 0.05])
    pts = ctl.model - d
    px = (pts[:, :2] / pts[:, 2:]) @ K[:2, :2].T + K[:2, 2]
    out = ctl.compute(px)
    assert np.allclose(out.twist[:3], -d, atol=1e-6) and np.allclose(out.twist[3:], 0, atol=1e-6)


def test_pbvs_takes_the_least_squares_pose_of_noisy_corners():
    from hvs_sim.control.pose import target_model, target_pose

    K = intrinsics(640, 480, 45)
    desired = np.array([[270.0, 205], [370, 205], [370, 275], [270, 275]])
    model = target_model(desired, 0.8, K)
    rng = np.random.default_rng(0)
    spread = {}
    for refine in (False, True):
        tilts = [cv2.Rodrigues(target_pose(model, K, desired + rng.normal(0, 0.07, desired.shape), refine)[0])[0][:2]
                 for _ in range(200)]
        spread[refine] = float(np.degrees(np.std(tilts)))
    assert spread[True] < 0.4 * spread[False] and spread[True] < 1.0  # 0.6° against 2.2°


def test_damped_pbvs_shrinks_only_what_the_corners_barely_see():
    K = intrinsics(640, 480, 45)
    desired = np.array([[270.0, 205], [370, 205], [370, 275], [270, 275]])  # a 15 cm target at 0.8 m
    plain = PBVSController(K, desired, 0.8, IBVSConfig(damping=0.0), dofs=DOF_NAMES)
    damped = PBVSController(K, desired, 0.8, IBVSConfig(damping=0.002), dofs=DOF_NAMES)
    from hvs_sim.control.features import interaction_matrix

    s = plain.points.s_star
    L = interaction_matrix(s, np.full(4, 0.8))
    _, sv, Vt = np.linalg.svd(L)
    weak, strong = Vt[-1], Vt[0]  # a sideways shift traded against a tilt; what moves the corners most
    assert np.allclose(damped.shrunk(weak, desired), weak * sv[-1] ** 2 / (sv[-1] ** 2 + (0.002 * sv[0]) ** 2),
                       atol=1e-9)
    assert np.allclose(damped.shrunk(strong, desired), strong, atol=1e-5)
    assert np.linalg.norm(damped.shrunk(weak, desired)) < 0.7  # the weak direction shrunk by ~40 %
    assert np.allclose(plain.compute(desired + 0.5).twist, PBVSController(K, desired, 0.8, IBVSConfig(),
                                                                         dofs=DOF_NAMES).compute(desired + 0.5).twist)


def test_pbvs_from_tracked_corners_converges_through_a_walk_by():
    sc = make_scenario("walk_by", mount="arm", start_offset=(0.02, -0.01, 0.03, math.radians(6), math.radians(4), 0),
                       camera=CameraConfig(width=640, height=480, sensor="robot_cell"))
    cfg = LoopConfig(steps=sc.n_frames + 60, keep_frames=False, controller="pbvs")
    loop = ServoLoop(sc, "hybrid", cfg, warp="homography")
    s = summarize_run(list(loop), cfg)
    assert loop.resolved.damping > 0  # tracked corners on six DOF: damped, as IBVS
    # the least-squares pose keeps the corners' noise off the command: held within the bounds to the end
    assert s["held_to_end"] and s["final_error_px"] < 0.3 and s["final_pose_error_mm"] < 5, s


def _run(offset, controller="ibvs", steps=150, **ibvs):
    sc = make_scenario("clear", mount="arm", start_offset=offset, camera=SMALL)
    cfg = LoopConfig(steps=steps, keep_frames=False, controller=controller, ibvs=IBVSConfig(**ibvs))
    recs = list(ServoLoop(sc, "ground_truth", cfg))
    return recs, summarize_run(recs, cfg)


def test_six_dof_ibvs_from_a_tilted_start_converges_with_the_pose_error_falling_exponentially():
    recs, s = _run(TILTED)
    assert s["controlled_dofs"] == list(DOF_NAMES)
    assert s["converged"] and s["final_pose_error_mm"] <= 1.0 and s["final_pose_error_deg"] <= 0.1, s
    mm = np.array([np.linalg.norm(r.pose_error[:3]) for r in recs])
    deg = np.array([np.linalg.norm(r.pose_error[3:]) for r in recs])
    assert mm[0] > 60 and deg[0] > 10
    for e in (mm, deg):
        ratios = e[30:120:30] / e[0:90:30]
        assert np.all(ratios < 0.5), ratios
    assert s["min_rank"] == 6 and s["max_condition_number"] > 1


def test_pbvs_converges_from_the_tilted_start():
    _, s = _run(TILTED, controller="pbvs")
    assert s["converged"] and s["final_pose_error_mm"] <= 1.0 and s["final_pose_error_deg"] <= 0.1, s
    assert s["controller"] == "pbvs" and s["target_out_of_view_steps"] == 0


def test_four_dofs_from_a_tilted_start_do_not_count_as_converged():
    # pitch and yaw are not controlled: the image error can shrink while the pose stays wrong
    _, s = _run(TILTED, steps=120, dofs=SIMILARITY_DOFS)
    assert s["controlled_dofs"] == list(SIMILARITY_DOFS)
    assert not s["converged"] and s["final_controlled_pose_error_mm"] > s["pose_bound"]["mm"], s


def test_start_offsets_are_checked():
    with pytest.raises(ConfigError, match="not fully in view"):
        ServoLoop(make_scenario("clear", mount="arm", start_offset=(0.1, 0, -0.2, 0, 0, math.radians(25))), "ground_truth")
    with pytest.raises(ConfigError, match="cannot be reached"):  # the camera pulled back onto the arm's base
        ServoLoop(make_scenario("clear", mount="arm", start_offset=(0, 0, -0.39, 0, 0, 0)), "ground_truth")
    with pytest.raises(ConfigError, match="too far"):
        make_scenario("clear", mount="arm", start_offset=(0, 0, 0, 0, math.radians(40), 0))
    with pytest.raises(ConfigError, match="6 finite numbers"):
        make_scenario("clear", mount="arm", start_offset=(0, 0, 0))
    # four values are the earlier (dx, dy, dz, roll) and mean no pitch or yaw
    assert make_scenario("clear", start_offset=(0, 0, 0, 0.1)).start_offset == (0, 0, 0, 0.1, 0, 0)


def test_start_pose_pulled_back_towards_the_base_is_reached():
    # continuation from the old home configuration failed within ~5 cm of the reference; now the arm reaches
    from hvs_sim.scene.world import Scene

    off = (0.0, 0.0, -0.2, 0.0, 0.0, 0.0)
    scene = Scene(make_scenario("clear", mount="arm", start_offset=off))
    pos, R = scene.camera_pose_cv()
    want_pos, want_R = offset_pose(*scene.reference_pose(), off)
    assert np.linalg.norm(pos - want_pos) < 1e-4 and np.allclose(R, want_R, atol=1e-4)
    assert np.allclose(scene.pose_error(), [0, 0, -200, 0, 0, 0], atol=0.1)


def test_run_json_carries_the_pose_error(tmp_path, capsys):
    out = tmp_path / "run.json"
    rc = main(["run", "--tracker", "ground_truth", "--scenario", "clear", "--steps", "5", "--width", "320", "--height",
               "240", "--start-offset", "0.03,-0.02,0.06,10,8,-8", "--controller", "pbvs", "--json", str(out)])
    assert rc == 0
    s = json.loads(out.read_text())
    for key in ("final_pose_error_mm", "final_pose_error_deg", "controlled_dofs", "pose_bound", "camera_path_m",
                "max_condition_number"):
        assert key in s
    assert s["controller"] == "pbvs" and s["final_pose_error_mm"] > 10 and not s["converged"]
    capsys.readouterr()
    assert main(["run", "--start-offset", "1,2,3"]) == 2
    assert "six numbers" in capsys.readouterr().err
    assert main(["run", "--tracker", "ground_truth", "--warp", "homography"]) == 2


def test_damped_pseudo_inverse_is_the_pseudo_inverse_at_zero_and_damps_the_weak_direction():
    from hvs_sim.control.features import damped_pinv, interaction_matrix

    K = intrinsics(640, 480, 45)
    desired = np.array([[260.0, 200], [380, 200], [380, 280], [260, 280]])
    L = interaction_matrix(IBVSController(K, desired, 0.8).s_star, np.full(4, 0.8))
    assert np.allclose(damped_pinv(L, 0.0), np.linalg.pinv(L))
    U, sv, _ = np.linalg.svd(L, full_matrices=False)
    mu = 0.005 * sv.max()
    D = damped_pinv(L, mu)
    weak, strong = U[:, -1], U[:, 0]  # image-space directions of the smallest and largest singular values
    assert np.linalg.norm(D @ weak) < 0.5 * np.linalg.norm(np.linalg.pinv(L) @ weak)
    assert np.allclose(D @ strong, np.linalg.pinv(L) @ strong, rtol=1e-3)
    with pytest.raises(ConfigError, match="damping"):
        IBVSConfig(damping=-0.1)


@pytest.mark.parametrize("motion", [cv2.MOTION_HOMOGRAPHY, cv2.MOTION_AFFINE])
def test_ecc_from_the_truth_stays_there(motion):
    """ECC on the frame its template was cut from, started at the template's own place, stays there: the template is
    cut from the pre-filtered frame (tracking/ecc.py). OpenCV smoothing the cropped template itself
    (reflected border) moved these corners by 0.01–0.1 px on this photo."""
    from hvs_sim.tracking.ecc import ecc_template, find_transform

    grey = cv2.cvtColor(photo("china"), cv2.COLOR_RGB2GRAY)
    x, y, w, h = ROI
    T = np.array([[1, 0, x], [0, 1, y], [0, 0, 1.0]])
    W0 = T if motion == cv2.MOTION_HOMOGRAPHY else T[:2]
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-6)
    _, W = find_transform(ecc_template(grey, ROI, 5), grey, W0, motion, criteria, None, 5)
    W = W if motion == cv2.MOTION_HOMOGRAPHY else np.vstack([W, [0, 0, 1]])
    corners = roi_corners((0, 0, w, h))
    assert np.abs(apply(W.astype(float), corners) - apply(T, corners)).max() < 1e-3
    # and it is the frame's own smoothing that matters: the crop smoothed alone is a different template
    own = cv2.GaussianBlur(grey[y:y + h, x:x + w].astype(np.float32), (5, 5), 0)
    assert np.abs(own - ecc_template(grey, ROI, 5))[:2].max() > 1.0


def test_ecc_homography_handed_over_scaled_ends_where_the_normalised_one_does():
    """OpenCV's Jacobian of the homography takes h33 = 1: find_transform normalises, so the scale of the matrix
    handed over does not matter (2× the matrix ended 5–9 px away before)."""
    from hvs_sim.tracking.ecc import ecc_template, find_transform

    grey = cv2.cvtColor(photo("flower"), cv2.COLOR_RGB2GRAY)
    Hm = perspective(np.random.default_rng(3).uniform(-3.0, 3.0, (4, 2)))
    frame = cv2.warpPerspective(grey, Hm, (W, H), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    start = np.array([[1, 0, ROI[0] + 1.0], [0, 1, ROI[1] - 1.0], [0, 0, 1]])
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-6)
    corners = roi_corners((0, 0, ROI[2], ROI[3]))
    found = [apply(find_transform(ecc_template(grey, ROI, 5), frame, k * start, cv2.MOTION_HOMOGRAPHY, criteria, None,
                                  5)[1].astype(float), corners) for k in (1.0, 2.0)]
    assert np.abs(found[0] - found[1]).max() < 1e-3
    assert np.abs(found[0] - apply(Hm, corners + ROI[:2])).max() < 0.5


def test_ecc_filter_size_is_checked():
    from hvs_sim.errors import ConfigError
    from hvs_sim.tracking.ecc import check_gauss

    assert check_gauss(5) == 5
    for bad in (0, 4, -3, 2.5):
        with pytest.raises(ConfigError, match="odd integer"):
            check_gauss(bad)



def test_intensity_refinement_brings_back_a_homography_that_feature_lk_leaves_pixels_off_on_a_weak_texture():
    # marble (procedural) under a 1.1× exposure change: the 8-parameter feature LK on the frame as it comes ends pixels
    # off; the intensity refinement (intensity_ic.py) from its answer recovers the warp when that is within its reach
    # (aligner.INTENSITY_REFINE_MAX_PX, 2 work px; 1 refused it). With the frame scaled to the template's exposure
    # first (normalise_lk_exposure, the default) the feature LK itself ends within 0.5 px
    from hvs_sim.scene.textures import natural_texture

    img = natural_texture("marble", W, H, seed=5)
    out = {}
    for refine in (False, True, "normalised"):
        tracker = make_tracker("deep_lk", warp="homography", refine_intensity=refine is True,
                               normalise_lk_exposure=refine == "normalised")
        tracker.init(img, ROI)
        errs = []
        for k in range(3):
            rng = np.random.default_rng([k, 7])
            Hm = perspective(rng.uniform(-4.0, 4.0, (4, 2)))
            frame = cv2.warpPerspective(img, Hm, (W, H), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
            frame = np.clip(1.1 * frame + rng.normal(0, 2.0, frame.shape), 0, 255).astype(np.uint8)  # exposure, noise
            tracker.seed(np.eye(3))
            tk = tracker.update(frame)
            true = cv2.perspectiveTransform(roi_corners(ROI)[None].astype(np.float64), Hm)[0]
            errs.append(np.linalg.norm(tk.corners - true, axis=1).max())
        out[refine] = np.array(errs)
    # warp 1: LK ends 4.4 px off at the ROI's corners, and the refinement's move, measured at the template's corner pixels in
    # work px, stays within the cap: refined to < 0.5 px. Warps 0 and 2 end 7–8 px off, beyond the cap, and stay as
    # LK left them (an occluder's pull is what the cap is for)
    assert out[False][1] > 4.0 and out[True][1] < 0.5, out
    assert np.all(out[True] <= out[False] + 1e-9) and out[False].min() > 2.0, out
    assert np.all(out["normalised"] < 0.5), out
