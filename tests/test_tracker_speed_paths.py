"""The hybrid's fast paths compute what the slower code they replaced computed.

numpy feature LK against a torch reference of the Gauss–Newton loop (grid_sample, steepest-descent
images), the histogram of exposure_gain against np.histogram, the search image shared by two global
matches against two plain matches, the fused conv + ReLU against eager layers; and the hybrid as a
whole stays deterministic. Images are synthetic (smoothed noise), so nothing depends on sample data.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
import torch

from hvs_sim.errors import ConfigError
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.aligner import AS_TAKEN_SKIP_OCCLUSION, Aligner, DeepLKConfig
from hvs_sim.tracking.feature_lk import (
    HUBER_K,
    MAD_TO_SIGMA,
    LKConfig,
    bilinear_rows,
    gradient_basis,
    sample_points,
    update_matrix,
)
from hvs_sim.tracking.global_match import GlobalMatcher
from hvs_sim.tracking.nets.vgg import vgg16_pool2
from hvs_sim.tracking.occlusion import (
    GAIN_BIN,
    GAIN_MIN_LEVEL,
    GAIN_RANGE,
    MIN_SUPPORT,
    OcclusionReference,
    _log_ratio_counts,
    aligned_patch,
    exposure_gain,
    occlusion_fraction,
)
from hvs_sim.tracking.warp import apply, pose_to_matrix, translate, warp_image

ROI = (120, 90, 96, 64)


def texture(seed: int, shape=(240, 320)) -> np.ndarray:
    """Smoothed colour noise: texture at several scales, uint8 RGB."""
    rng = np.random.default_rng(seed)
    img = np.zeros((*shape, 3), np.float32)
    for sigma, amp in ((1.0, 40.0), (3.0, 60.0), (8.0, 80.0)):
        img += amp * cv2.GaussianBlur(rng.standard_normal((*shape, 3)).astype(np.float32), (0, 0), sigma)
    return np.clip(128 + img, 0, 255).astype(np.uint8)


def moved(img: np.ndarray, pose, center) -> np.ndarray:
    A = pose_to_matrix(pose, center)
    return cv2.warpAffine(img, A[:2], (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def test_numpy_bilinear_matches_grid_sample_inside_and_at_the_border():
    rng = np.random.default_rng(0)
    fmap = torch.from_numpy(rng.random((16, 11, 13), dtype=np.float32))
    pts = np.c_[rng.uniform(-2, 15, 500), rng.uniform(-2, 13, 500)]  # some beyond the map: border padding
    ref, u = sample_points(fmap, pts, np.zeros(2), 1)
    ours = bilinear_rows(np.ascontiguousarray(fmap.permute(1, 2, 0).numpy()), u[:, 0].copy(), u[:, 1].copy())
    assert np.abs(ours - ref.numpy()).max() < 1e-5


def _reference_align(lk, feats, origin, crop_shape, M0, eps):
    """The IC-LK loop as it was in torch (grid_sample, (N·C × P) steepest-descent product), with the
    paper's stopping rule: the numpy loop must land on the same warp."""
    M, P = M0.copy(), lk.n_params
    H_crop, W_crop = crop_shape
    lo = origin + lk.config.border
    hi = origin + np.array([W_crop - 1, H_crop - 1]) - lk.config.border
    for level, iters in zip(lk.levels, lk.config.iterations):
        fmap = feats[level.name]
        for _ in range(iters):
            pts = lk.to_work(M, level.pts)
            valid = (pts[:, 0] >= lo[0]) & (pts[:, 0] <= hi[0]) & (pts[:, 1] >= lo[1]) & (pts[:, 1] <= hi[1])
            sampled, _ = sample_points(fmap, pts[valid], origin, level.stride)
            err = sampled - level.feats[valid]
            r = torch.linalg.vector_norm(err, dim=1).double().numpy()
            k = HUBER_K * max(MAD_TO_SIGMA * np.median(r), 1e-6)
            w = np.where(r <= k, 1.0, k / np.maximum(r, 1e-12))
            sd = level.sd.view(-1, err.shape[1], P)[torch.from_numpy(valid)].reshape(-1, P)
            b = ((err * torch.from_numpy(w).float()[:, None]).reshape(1, -1) @ sd)[0].double().numpy()
            H = (w @ level.hess[valid]).reshape(P, P)
            dp = np.linalg.solve(H, b)
            M = M @ np.linalg.inv(update_matrix(dp, lk.warp))
            M = M / M[2, 2]
            if lk.update_size(dp) < eps * level.stride:
                break
    return M


@pytest.mark.parametrize("warp", ["similarity", "homography"])
def test_numpy_feature_lk_lands_where_the_torch_loop_does(warp):
    img = texture(1)
    al = Aligner(DeepLKConfig(warp=warp, lk=LKConfig(coarse_eps=None)))  # the paper's stopping rule
    work = al.set_template(img, ROI)
    lk = al.lk_engine
    for pose in ((1.3, -0.8, 0.02, 1.01), (-2.5, 1.7, -0.04, 0.97)):
        frame = al.work_image(moved(img, pose, al.center0))
        A_work = np.eye(3)
        x0, y0, x1, y1 = al.crop_box(apply(A_work, al.t_corners), work.shape)
        feats = al.features(frame, x0, y0, x1, y1)
        origin = np.array([x0, y0], float)
        M0 = al.N @ A_work @ al.N_inv
        ours = lk.align(feats, origin, (y1 - y0, x1 - x0), M0).M
        ref = _reference_align(lk, feats, origin, (y1 - y0, x1 - x0), M0, lk.config.eps)
        box = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
        assert np.abs(al.rho * (apply(ours, box) - apply(ref, box))).max() < 1e-3  # work px


def test_coarse_level_stopping_rule_moves_the_answer_by_less_than_a_thousandth_of_a_pixel():
    img = texture(2)
    answers = []
    for coarse_eps in (None, LKConfig().coarse_eps):
        al = Aligner(DeepLKConfig(lk=LKConfig(coarse_eps=coarse_eps)))
        al.set_template(img, ROI)
        frame = al.work_image(moved(img, (1.7, 1.1, 0.03, 1.02), al.center0))
        out = al.align(frame, np.eye(3))
        answers.append(apply(al.to_full(out.A_work), al.center0[None])[0])
    assert np.abs(answers[0] - answers[1]).max() < 2e-3  # full-resolution px


def test_predicted_stop_ends_no_later_and_lands_within_a_hundredth_of_a_pixel():
    img = texture(3)
    runs = []
    for predict_stop in (False, True):
        al = Aligner(DeepLKConfig(lk=LKConfig(predict_stop=predict_stop)))
        al.set_template(img, ROI)
        frame = al.work_image(moved(img, (-1.2, 2.1, -0.02, 0.99), al.center0))
        out = al.align(frame, np.eye(3))
        runs.append((out.lk.result.iterations, apply(al.to_full(out.A_work), al.center0[None])[0]))
    assert runs[1][0] <= runs[0][0]
    assert np.abs(runs[1][1] - runs[0][1]).max() < 1e-2


def test_lk_config_refuses_a_non_positive_stopping_threshold():
    with pytest.raises(ConfigError):
        LKConfig(coarse_eps=0.0)
    with pytest.raises(ConfigError):
        LKConfig(eps=-1.0)


def _histogram_gain(patch, template, inside):
    """exposure_gain as written with np.histogram (before the bin counting was made direct)."""
    t, p = template.astype(np.float32), patch.astype(np.float32)
    use = (t > GAIN_MIN_LEVEL) & (inside[..., None] if t.ndim == 3 else inside)
    if use.sum() < 16:
        return 1.0
    lo, hi = np.log(GAIN_RANGE)
    r = np.log(np.maximum(p[use], 0.5) / t[use])
    r = r[(r >= lo) & (r <= hi)]
    if r.size < 16:
        return 1.0
    hist, edges = np.histogram(r, bins=max(1, int(np.ceil((hi - lo) / GAIN_BIN))), range=(lo, hi))
    hist = np.convolve(hist, np.ones(3), mode="same")
    k = int(np.argmax(hist))
    near = r[np.abs(r - 0.5 * (edges[k] + edges[k + 1])) <= 1.5 * GAIN_BIN]
    return float(np.exp(np.median(near))) if near.size else 1.0


def test_exposure_gain_bins_exactly_as_np_histogram():
    rng = np.random.default_rng(3)
    lo, hi = np.log(GAIN_RANGE)
    n_bins = max(1, int(np.ceil((hi - lo) / GAIN_BIN)))
    edges = np.linspace(lo, hi, n_bins + 1)
    for _ in range(50):
        r = rng.uniform(lo, hi, 2000).astype(np.float32)
        r[:40] = edges[rng.integers(0, n_bins + 1, 40)].astype(np.float32)  # values on (rounded) edges
        r = r[(r >= lo) & (r <= hi)]
        assert np.array_equal(_log_ratio_counts(r), np.histogram(r, bins=n_bins, range=(lo, hi))[0])
    img = texture(4)
    template = img[40:100, 60:150]
    for gain in (0.6, 0.9, 1.0, 1.25, 1.8):
        for grey in (False, True):
            patch = np.clip(img[42:102, 61:151] * gain, 0, 255).astype(np.uint8)
            tpl = template
            if grey:
                patch, tpl = cv2.cvtColor(patch, cv2.COLOR_RGB2GRAY), cv2.cvtColor(template, cv2.COLOR_RGB2GRAY)
            inside = np.ones(patch.shape[:2], bool)
            inside[:, :10] = False
            assert exposure_gain(patch, tpl, inside) == _histogram_gain(patch, tpl, inside)


def test_shared_search_image_gives_the_same_matches():
    grey = cv2.cvtColor(texture(5), cv2.COLOR_RGB2GRAY)
    matcher = GlobalMatcher()
    search = matcher.prepare(grey)
    for y, x in ((50, 60), (120, 200)):
        template = grey[y:y + 40, x:x + 56].copy()
        a, b = matcher.match(grey, template), matcher.match(search, template)
        assert np.array_equal(a.center, b.center) and a.score == b.score and a.second == b.second
    flat = matcher.match(np.full_like(grey, 7), grey[:40, :56].copy())
    assert flat.score == 0.0 and np.all(np.isnan(flat.center))


def test_fused_conv_relu_gives_the_eager_layers_values():
    net = vgg16_pool2()
    if not net.fused:
        pytest.skip("this torch build has no fused oneDNN convolution")
    x = torch.from_numpy(cv2.cvtColor(texture(6, (48, 64)), cv2.COLOR_RGB2GRAY).astype(np.float32))[None, None]
    levels = ("pool2", "pool1", "conv1_2")
    with torch.inference_mode():
        fused = net(x, levels=levels)
        net.fused = False
        try:
            eager = net(x, levels=levels)
        finally:
            net.fused = True
    for k in levels:
        assert torch.equal(fused[k], eager[k])


@pytest.mark.parametrize("warp", ["similarity", "homography"])
def test_hybrid_is_deterministic_and_reports_its_stages(warp):
    img = texture(7)
    c = np.array([ROI[0] + (ROI[2] - 1) / 2, ROI[1] + (ROI[3] - 1) / 2])
    frames = [moved(img, (0.7 * k, -0.4 * k, 0.004 * k, 1 + 0.002 * k), c) for k in range(8)]
    runs = []
    for _ in range(2):
        tr = make_tracker("hybrid", warp=warp)
        tr.init(frames[0], ROI)
        tracks = [tr.update(f) for f in frames[1:]]
        runs.append(np.array([t.corners for t in tracks]))
        assert all(t.mode == "align" for t in tracks)
        assert {"prepare", "coarse", "occlusion", "features", "lk"} <= set(tr.stage_ms)
        assert all(v >= 0 for v in tr.stage_ms.values())
    assert np.array_equal(runs[0], runs[1])
    truth = apply(pose_to_matrix((0.7 * 7, -0.4 * 7, 0.028, 1.014), c), c[None])[0]
    assert np.linalg.norm(tracks[-1].center - truth) < 0.3


def test_gradient_basis_is_orthonormal_and_keeps_most_of_the_gradient_energy():
    al = Aligner(DeepLKConfig())
    al.set_template(texture(8), ROI)
    level = al.lk_engine.level("conv1_2")  # full channels: the basis is computed from these copies
    gx, gy = level.gx, level.gy
    assert gradient_basis(gx, gy, gx.shape[1]) is None  # no reduction asked: no projection
    B = gradient_basis(gx, gy, 8)
    assert B.shape == (gx.shape[1], 8) and B.dtype == np.float32
    assert np.allclose(B.T @ B, np.eye(8), atol=1e-5)
    energy = lambda P: float(np.sum((gx @ P) ** 2) + np.sum((gy @ P) ** 2))
    total = energy(np.eye(gx.shape[1], dtype=np.float32))
    rng = np.random.default_rng(0)
    random_basis = np.linalg.qr(rng.standard_normal((gx.shape[1], 8)))[0].astype(np.float32)
    assert energy(B) > 0.8 * total and energy(B) > 2 * energy(random_basis)


@pytest.mark.parametrize("warp", ["similarity", "homography"])
def test_lk_in_the_gradient_subspace_lands_where_the_full_lk_does(warp):
    img = texture(9)
    answers = {}
    for channels in (None, 8):
        lk = LKConfig(levels=("pool1", "conv1_2"), iterations=(15, 8), channels=channels)
        al = Aligner(DeepLKConfig(warp=warp, lk=lk, margin=5))
        al.set_template(img, ROI)
        assert all((lv.basis is None) == (channels is None) for lv in al.lk_engine.levels)
        for pose in ((0.9, -0.6, 0.02, 1.01), (-1.4, 1.1, -0.03, 0.98)):
            frame = al.work_image(moved(img, pose, al.center0))
            A = al.to_full(al.align(frame, np.eye(3)).A_work)
            truth = pose_to_matrix(pose, al.center0)
            corners = np.array([[ROI[0], ROI[1]], [ROI[0] + ROI[2], ROI[1] + ROI[3]]], float)
            err = np.abs(apply(A, corners) - apply(truth, corners)).max()
            assert err < 0.1, (channels, pose, err)  # full-resolution px
            answers.setdefault(pose, []).append(apply(A, corners))
    for a, b in answers.values():
        assert np.abs(a - b).max() < 0.05


def test_lk_channels_must_be_a_positive_int_or_none():
    for bad in (0, -3, 2.5, True, "8"):
        with pytest.raises(ConfigError, match="channels"):
            LKConfig(channels=bad)


def test_aligned_patch_skips_the_mask_warp_only_where_every_pixel_is_inside():
    rng = np.random.default_rng(1)
    grey = rng.integers(0, 256, (120, 160), np.uint8)
    for i in range(400):
        A = np.eye(3)
        A[:2, :2] += rng.normal(0, 0.2, (2, 2))
        A[:2, 2] = rng.uniform(-40, 150, 2)
        if i % 2:
            A[2, :2] = rng.normal(0, 2e-3, 2)  # perspective
        origin, shape = rng.uniform(0, 100, 2), (int(rng.integers(4, 40)), int(rng.integers(4, 40)))
        _, inside = aligned_patch(grey, A, origin, shape)
        M = A @ np.array([[1, 0, origin[0]], [0, 1, origin[1]], [0, 0, 1.0]])
        ref = warp_image(np.full(grey.shape, 255, np.uint8), M, shape[::-1],
                         flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT) > 0
        assert np.array_equal(inside, ref), i


def test_the_search_with_the_template_as_taken_runs_only_when_the_rectified_one_does_not_confirm():
    img = texture(10)
    c = np.array([ROI[0] + (ROI[2] - 1) / 2, ROI[1] + (ROI[3] - 1) / 2])
    pose = (1.0, -0.5, 0.05, 1.04)  # turned and scaled: the search template is rectified
    cases = [  # (always_search_as_taken, what is wrong, searches expected)
        (False, None, 1), (True, None, 2),
        (False, "estimate", 2),  # 12 px from the target: the rectified search does not confirm it
        (False, "hidden", 2),  # a quarter of the target covered: OP_t over AS_TAKEN_SKIP_OCCLUSION
        (False, "op_over", 2),  # confirmed, but OP_t at the estimate just over the bound
        (False, "op_under", 1),  # confirmed, OP_t just under it
        (False, "keep_current", 2),  # deep_lk's search: global-match seeds only, both searches always
    ]
    for always, wrong, searches in cases:
        al = Aligner(DeepLKConfig(always_search_as_taken=always))
        al.set_template(img, ROI)
        A = pose_to_matrix(pose, c)
        if wrong == "estimate":
            A = pose_to_matrix((pose[0] + 12.0, pose[1], pose[2], pose[3]), c)
        frame = moved(img, pose, c)
        if wrong == "hidden":
            frame[ROI[1]:ROI[1] + ROI[3], ROI[0]:ROI[0] + ROI[2] // 4] = 0
        if wrong in ("op_over", "op_under"):  # the OP_t rule alone decides: the rectified search confirms
            op_value = AS_TAKEN_SKIP_OCCLUSION + (0.01 if wrong == "op_over" else -0.01)
            al.occlusion = lambda work, cand, _v=op_value: _v
            first = al.matcher.match(al.matcher.prepare(al.work_image(frame)), al.rectified_template(A))
            assert first.score >= al.config.match_threshold
            assert np.linalg.norm(first.center - apply(al.to_work(A), al.c_work[None])[0]) <= al.config.reinit_px
        calls = []

        def counted(*a, _match=al.matcher.match, _calls=calls):
            _calls.append(1)
            return _match(*a)

        al.matcher.match = counted
        m, seed, op, _ = al.coarse(al.work_image(frame), A, keep_current=wrong != "keep_current")
        assert len(calls) == searches, (always, wrong)
        if wrong in ("op_over", "op_under"):
            continue
        assert (op > AS_TAKEN_SKIP_OCCLUSION) == (wrong == "hidden")
        if wrong == "hidden":
            continue
        assert m.score > 0.8
        assert np.linalg.norm(al.to_full(seed)[:2, 2] - pose_to_matrix(pose, c)[:2, 2]) < 2.0


def test_the_hybrid_runs_the_fast_lk_and_its_variants_keep_what_they_need():
    from hvs_sim.tracking.hybrid import HYBRID_LK, HYBRID_MARGIN

    fast = make_tracker("hybrid")
    assert fast.config.lk == HYBRID_LK and fast.config.margin == HYBRID_MARGIN
    assert "pool2" not in HYBRID_LK.levels and HYBRID_LK.channels == 8
    full = make_tracker("hybrid_full_lk")
    assert full.config.lk.levels == ("pool2", "pool1", "conv1_2") and full.config.lk.channels is None
    assert full.config.margin == 8 and full.config.always_search_as_taken and not full.config.search_near_first
    assert (full.config.lk.eps, full.config.lk.coarse_eps) == (LKConfig().eps, LKConfig().coarse_eps)
    assert fast.config.search_near_first and HYBRID_LK.eps > LKConfig().eps
    assert not make_tracker("deep_lk").config.search_near_first
    assert not make_tracker("hybrid_residual").config.search_near_first
    # the residual regressor reads pool2: its variants keep deep_lk's LK
    assert "pool2" in make_tracker("hybrid_residual").config.lk.levels
    assert make_tracker("deep_lk").config.lk == LKConfig()
    assert not fast.config.always_search_as_taken
    assert make_tracker("hybrid_residual").config.always_search_as_taken  # deep_lk's alignment, as before
    assert make_tracker("deep_lk").config.always_search_as_taken
    # an lk dict changes the tracker's own LK only in what it names
    assert make_tracker("hybrid", lk={"channels": 16}).config.lk == replace(HYBRID_LK, channels=16)
    assert make_tracker("hybrid_full_lk", lk={"channels": 16}).config.lk == replace(full.config.lk, channels=16)
    assert make_tracker("deep_lk", lk={"channels": np.int64(4)}).config.lk.channels == 4
    with pytest.raises(ConfigError, match="lk must be an LKConfig"):
        make_tracker("hybrid", lk="fast")
    with pytest.raises(ConfigError, match="always_search_as_taken"):
        make_tracker("hybrid", always_search_as_taken="no")
    with pytest.raises(ConfigError, match="search_near_first"):
        make_tracker("hybrid", search_near_first=1)
    with pytest.raises(ConfigError, match="lk"):
        make_tracker("hybrid", lk={"chanels": 16})


def _op_as_written(patch, template, inside, tau, normalise):
    """occlusion_fraction as written before OcclusionReference: everything per call, np.histogram's gain."""
    t, p = template.astype(np.float32), patch.astype(np.float32)

    def differs(ref):
        d = np.abs(p - ref) > tau
        if d.ndim == 3:
            d = d.any(axis=2)
        if inside is not None:
            d |= ~inside
        return float(d.mean())

    raw = differs(t)
    if not normalise:
        return raw
    everywhere = np.ones(patch.shape[:2], bool) if inside is None else inside
    op = differs(t * np.float32(_histogram_gain(patch, template, everywhere)))
    return op if 1.0 - op >= MIN_SUPPORT else max(op, raw)


def test_occlusion_reference_gives_the_per_call_values_exactly():
    img = texture(6)
    template = img[40:100, 60:150]
    checked = 0
    for gain in (0.55, 0.9, 1.0, 1.3, 1.9):
        for grey in (False, True):
            patch = np.clip(img[41:101, 62:152] * gain, 0, 255).astype(np.uint8)
            patch[10:40, 20:60] = (30, 200, 90)  # an occluder
            tpl = template
            if grey:
                patch, tpl = cv2.cvtColor(patch, cv2.COLOR_RGB2GRAY), cv2.cvtColor(template, cv2.COLOR_RGB2GRAY)
            part = np.ones(patch.shape[:2], bool)
            part[:, :12] = False
            for inside in (None, np.ones(patch.shape[:2], bool), part):
                for normalise in (False, True):
                    want = _op_as_written(patch, tpl, inside, 30, normalise)
                    for t in (tpl, tpl.astype(np.float32)):  # the table's path and the generic one
                        ref = OcclusionReference(t, 30, normalise)
                        assert ref(patch, inside) == want
                        assert occlusion_fraction(patch, t, inside, 30, normalise) == want
                        checked += 1
                    everywhere = np.ones(patch.shape[:2], bool) if inside is None else inside
                    assert OcclusionReference(tpl).gain(patch, inside) == _histogram_gain(patch, tpl, everywhere)
    assert checked == 120


def test_match_near_finds_what_the_global_match_finds_there_and_nothing_beyond_its_window():
    grey = cv2.cvtColor(texture(7), cv2.COLOR_RGB2GRAY)
    matcher = GlobalMatcher()
    template = grey[80:120, 100:156].copy()
    frame = cv2.cvtColor(moved(texture(7), (3.4, -2.3, 0.0, 1.0), np.array([160.0, 120.0])), cv2.COLOR_RGB2GRAY)
    search = matcher.prepare(frame)
    m = matcher.match(search, template)
    for offset in ((0.0, 0.0), (2.5, -1.5), (-4.0, 3.0)):
        near = matcher.match_near(search, template, m.center + offset)
        assert near is not None and near.second == -1.0
        # the same place; NCC over a smaller region differs in its float32 rounding (OpenCV correlates by DFT)
        assert np.abs(near.center - m.center).max() < 1e-3 and abs(near.score - m.score) < 1e-4
    assert matcher.match_near(search, template, m.center + (15.0, 0.0)) is None  # the peak is beyond the window
    assert matcher.match_near(search, np.full_like(template, 9), m.center) is None  # a blank template


def _counting(f, calls: dict, name: str):
    def counted(*a):
        calls[name] += 1
        return f(*a)
    return counted


def test_a_search_near_the_estimate_that_confirms_it_replaces_the_global_searches():
    img = texture(10)
    c = np.array([ROI[0] + (ROI[2] - 1) / 2, ROI[1] + (ROI[3] - 1) / 2])
    pose = (1.0, -0.5, 0.05, 1.04)
    for wrong, near_calls, global_calls in ((None, 1, 0), ("estimate", 1, 2), ("hidden", 0, 2)):
        runs = []
        for near_first in (True, False):
            al = Aligner(DeepLKConfig(always_search_as_taken=False, search_near_first=near_first))
            al.set_template(img, ROI)
            A = pose_to_matrix((pose[0] + (12.0 if wrong == "estimate" else 0.0), *pose[1:]), c)
            frame = moved(img, pose, c)
            if wrong == "hidden":
                frame[ROI[1]:ROI[1] + ROI[3], ROI[0]:ROI[0] + ROI[2] // 4] = 0
            if wrong == "estimate":  # an unhidden look at the wrong place: the near search runs and does not confirm
                al.occlusion = lambda work, cand: 0.05
            calls = {"match": 0, "match_near": 0}
            for name in calls:
                setattr(al.matcher, name, _counting(getattr(al.matcher, name), calls, name))
            runs.append(al.coarse(al.work_image(frame), A))
            if near_first:
                assert (calls["match_near"], calls["match"]) == (near_calls, global_calls), wrong
        (m1, seed1, op1, cur1), (m2, seed2, op2, cur2) = runs
        assert np.array_equal(seed1, seed2) and op1 == op2 and cur1 == cur2  # the same seed either way
        assert abs(m1.score - m2.score) < 1e-4 and np.abs(m1.center - m2.center).max() < 1e-3
        if wrong is None:
            assert cur1 and np.linalg.norm(al.to_full(seed1)[:2, 2] - pose_to_matrix(pose, c)[:2, 2]) < 2.0


def test_colour_near_the_patch_is_the_whole_working_image_there():
    img = texture(11, shape=(480, 640))
    al = Aligner(DeepLKConfig())
    al.set_template(img, (250, 190, 120, 80))
    whole = al.work_colour(img)
    rng = np.random.default_rng(5)
    reference = OcclusionReference(al.template_patch(whole), 30, True)
    for i in range(60):
        # drifted, turned, scaled and (every third) tilted warps, some running off the frame's edges
        A = pose_to_matrix((rng.uniform(-140, 140), rng.uniform(-100, 100), rng.uniform(-0.5, 0.5), rng.uniform(0.7, 1.4)),
                           al.c_work)
        tilted = i % 3 == 0
        if tilted:  # a homography: cropped too (OpenCV's perspective warp rounds a moved one a little differently)
            A = A @ np.array([[1, 0, 0], [0, 1, 0], [rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3), 1]])
        near, offset = al.work_colour_near(img, A)
        x0, y0 = offset.astype(int)
        assert np.array_equal(near, whole[y0:y0 + near.shape[0], x0:x0 + near.shape[1]])
        assert near.shape != whole.shape or not np.all(np.isfinite(apply(A, al.t_corners)))
        a = aligned_patch(whole, A, al.t_origin, (al.th, al.tw))
        b = aligned_patch(near, translate(A, -offset), al.t_origin, (al.th, al.tw))
        assert np.array_equal(a[1], b[1]), i
        # the same samples but where OpenCV rounds a sample point to the other 1/32 px
        changed = np.abs(a[0].astype(int) - b[0].astype(int))
        assert np.mean(changed > 0) < 0.002 and changed.max() <= 2, i  # 300 warps: ≤ 0.04 %, by 1 level (tilted: ≤ 0.06 %)
        assert abs(reference(*a) - reference(*b)) <= 0.001
    odd = np.ascontiguousarray(img[:479])  # a height the working scale does not divide: the whole image
    near, offset = al.work_colour_near(odd, np.eye(3))
    assert np.array_equal(near, al.work_colour(odd)) and not offset.any()
