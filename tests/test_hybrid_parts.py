"""The hybrid's parts on their own: registry, Mode, atomic init and trackability, exposure-normalised
OP_t, the residual's verification, verified re-acquisition."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from hvs_sim.errors import ConfigError, InputError, StateError
from hvs_sim.scene.textures import natural_texture
from hvs_sim.tracking import TRACKERS, Mode, make_tracker
from hvs_sim.tracking.global_match import GlobalMatcher, Match
from hvs_sim.tracking.occlusion import occlusion_fraction
from hvs_sim.tracking.warp import apply, pose_to_matrix

ROI = (250, 170, 120, 84)


def _frame(name: str = "brick", seed: int = 3) -> np.ndarray:
    return natural_texture(name, 640, 480, seed)


def _shifted(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    import cv2

    M = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(img, M, img.shape[1::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def test_registry_names_build_with_distinct_colours_and_unknown_settings_are_clear():
    colours = [spec.colour for spec in TRACKERS.values()]
    assert len(set(colours)) == len(colours)
    tr = make_tracker("hybrid_paper")
    assert tr.name == "hybrid_paper" and not tr.hconfig.background and not tr.hconfig.colour_occlusion
    assert not tr.config.normalise_exposure and not tr.hconfig.verify_reacquisition
    assert make_tracker("hybrid_cv").hconfig.predictor == "constant_velocity"
    with pytest.raises(ConfigError, match="accepted: .*occlusion_gate"):
        make_tracker("hybrid", occlusion_gat=0.3)
    with pytest.raises(ConfigError, match="gate_after_alignment must be True or False, got 'no'"):
        make_tracker("hybrid", gate_after_alignment="no")
    with pytest.raises(ConfigError, match="ratio"):
        make_tracker("sift", ratioo=0.5)
    with pytest.raises(ConfigError, match="lk_perspective=True cannot run with the residual regressor"):
        make_tracker("hybrid", residual=True, lk_perspective=True)
    assert make_tracker("hybrid").hconfig.lk_perspective  # the regressor reads the similarity LK's answers:
    assert not make_tracker("hybrid", residual=True).hconfig.lk_perspective  # without it by default


def test_mode_is_an_enum_that_reads_as_its_string():
    img = _frame()
    tr = make_tracker("hybrid")
    tr.init(img, ROI)
    tk = tr.update(_shifted(img, 1.5, -0.5))
    assert tk.mode is Mode.ALIGN and tk.mode == "align" and f"{tk.mode}" == "align"
    assert tk.confidence == pytest.approx(1.0 - tk.occlusion)


def test_confidence_falls_while_the_target_is_hidden_and_returns_when_it_is_aligned_again():
    img = _frame()
    tr = make_tracker("hybrid")
    tr.init(img, ROI)
    before = tr.update(img).confidence
    covered = img.copy()
    covered[150:280, 230:400] = (60, 40, 30)  # a brown coat over the whole target; the wall stays in view
    hidden = [tr.update(covered) for _ in range(8)]
    assert all(tk.mode != Mode.ALIGN for tk in hidden)
    conf = [tk.confidence for tk in hidden]
    assert conf[0] < before and all(b < a for a, b in itertools.pairwise(conf)) and conf[-1] > 0.0
    again = tr.update(img)
    assert again.mode is Mode.ALIGN and again.confidence == pytest.approx(1.0 - again.occlusion)


def test_flat_template_is_refused_and_the_tracker_stays_uninitialised():
    img = _frame()
    img[150:280, 230:400] = (135, 180, 235)  # plain sky where the ROI is
    rng = np.random.default_rng(0)
    noisy = np.clip(img + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)  # sensor noise on it
    for name in ("deep_lk", "hybrid"):
        tr = make_tracker(name)
        with pytest.raises(InputError, match="a flat patch"):
            tr.init(noisy, ROI)
        with pytest.raises(StateError):
            tr.update(noisy)
        tr = make_tracker(name, allow_untrackable=True)
        tr.init(noisy, ROI)
        tk = tr.update(noisy)
        assert 0.0 <= tk.confidence < 0.5 and np.isfinite(tk.pose).all()
    tr = make_tracker("hybrid")
    assert tr.init(_frame(), ROI).confidence == 1.0  # textured: full confidence


def test_a_single_edge_is_refused_and_a_weak_lattice_accepted_with_a_note():
    """Trackability as advice: refused only where no tracker can localise; a faint but two-dimensional target (thin
    low-contrast struts against the sky) is tracked, with a note and a lowered confidence."""
    rng = np.random.default_rng(1)
    sky = np.full((360, 480, 3), (135, 180, 235), np.float64)
    edge = sky.copy()
    edge[:, 240:] = (90, 90, 100)  # one straight vertical edge through the ROI
    lattice = sky.copy()
    yy, xx = np.mgrid[0:360, 0:480]
    struts = (np.abs((xx + yy) % 30 - 15) < 1) | (np.abs((xx - yy) % 30 - 15) < 1)
    lattice[struts] -= 10  # four grey levels of contrast
    roi = (180, 120, 120, 100)
    noisy = [np.clip(img + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8) for img in (edge, lattice)]
    with pytest.raises(InputError, match="one direction only"):
        make_tracker("hybrid").init(noisy[0], roi)
    tr = make_tracker("hybrid")
    assert 0 < tr.init(noisy[1], roi).confidence < 1
    assert len(tr.notes) == 1 and tr.notes[0].startswith("weak template")
    assert make_tracker("hybrid").init(_frame(), ROI).confidence == 1.0


def test_exposure_change_alone_is_not_occlusion_but_a_cover_is():
    tex = _frame("fabric", 1)[100:184, 100:220]
    brighter = np.clip(tex.astype(np.float32) * 1.3, 0, 255).astype(np.uint8)
    darker = (tex.astype(np.float32) * 0.7).astype(np.uint8)
    assert occlusion_fraction(brighter, tex) > 0.3  # the paper's raw OP_t reads the exposure step as occlusion
    for frame in (brighter, darker):
        assert occlusion_fraction(frame, tex, normalise_exposure=True) < 0.05
    covered = brighter.copy()
    covered[:, :36] = (40, 35, 30)  # a dark coat over the left 30 %, after the exposure step
    assert occlusion_fraction(covered, tex) > 0.4  # raw: over the 40 % gate
    assert occlusion_fraction(covered, tex, normalise_exposure=True) == pytest.approx(0.3, abs=0.05)
    full = np.full_like(tex, 35)
    assert occlusion_fraction(full, tex, normalise_exposure=True) >= occlusion_fraction(full, tex) > 0.4  # never lower


class _WildResidual(torch.nn.Module):
    """A regressor trained on other textures: a large correction whatever it sees."""

    def forward(self, feats, warp):
        return torch.tensor([[6.0, -5.0, 0.05, 0.04]]).expand(len(feats), 4)


def test_verified_residual_never_turns_an_lk_alignment_into_a_failure():
    img = _frame("foliage", 2)
    plain = make_tracker("deep_lk")
    verified = make_tracker("deep_lk_residual", verify_residual=True)
    unverified = make_tracker("deep_lk_residual", verify_residual=False)
    c = np.array([ROI[0] + (ROI[2] - 1) / 2, ROI[1] + (ROI[3] - 1) / 2])
    for tr in (verified, unverified):
        tr.aligner.residual_net = _WildResidual()
    errors = {id(t): [] for t in (plain, verified, unverified)}
    for k, (dx, dy, th) in enumerate([(1.2, -0.7, 0.01), (-2.3, 1.4, -0.02), (3.1, 2.2, 0.0), (0.4, -2.6, 0.03)]):
        frame = _shifted(img, 0, 0)
        A = pose_to_matrix((dx, dy, th, 1.0), c)
        import cv2

        frame = cv2.warpAffine(img, A[:2], img.shape[1::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        for tr in (plain, verified, unverified):
            tr.init(img, ROI)
            tk = tr.update(frame)
            errors[id(tr)].append((tk.mode, float(np.linalg.norm(tk.center - (c + (dx, dy))))))
        assert errors[id(plain)][k][0] == "align" and errors[id(plain)][k][1] < 0.2
        assert errors[id(verified)][k] == errors[id(plain)][k]  # the wild correction was refused
    assert any(m != "align" or e > 1.0 for m, e in errors[id(unverified)])  # and applied, it does harm


def test_second_ncc_peak_tells_a_unique_match_from_a_self_similar_one():
    img = _frame("gravel", 0)
    grey = img.mean(2).astype(np.uint8)
    unique = GlobalMatcher().match(grey, grey[170:254, 250:370].copy())
    periodic = np.tile(grey[170:200, 250:290], (16, 16))[:480, :640].copy()  # a texture that repeats itself
    repeated = GlobalMatcher().match(periodic, periodic[170:254, 250:370].copy())
    assert unique.score - unique.second > 0.2
    assert repeated.score - repeated.second < 0.05


def test_a_far_reacquisition_needs_a_unique_match_on_consecutive_frames():
    img = _frame()
    tr = make_tracker("hybrid", verify_reacquisition=True, surroundings_veto_frames=0)
    tr.init(img, ROI)
    c = tr.hconfig
    far = pose_to_matrix((60.0, 0.0, 0.0, 1.0), tr.center0)
    near = pose_to_matrix((c.reacquire_px / 2, 0.0, 0.0, 1.0), tr.center0)
    assert tr._verified(near, Match(np.zeros(2), 0.8, 0.79))  # close to the estimate: no test
    assert not tr._verified(far, Match(np.zeros(2), 0.8, 0.78))  # a look-alike elsewhere: refused
    unique = Match(np.zeros(2), 0.9, 0.3)
    seen = [tr._verified(far, unique) for _ in range(c.reacquire_frames)]
    assert seen == [False] * (c.reacquire_frames - 1) + [True]
    unverified = make_tracker("hybrid", verify_reacquisition=False)
    unverified.init(img, ROI)
    assert unverified._verified(far, Match(np.zeros(2), 0.8, 0.78))


def test_a_far_jump_the_surroundings_contradict_is_held_back():
    # a unique match far from a static target's estimate, while every frame since the alignment was measured on the
    # surroundings (as right after init): a look-alike, refused until seen on surroundings_veto_frames frames
    img = _frame()
    tr = make_tracker("hybrid", surroundings_veto_frames=5)
    tr.init(img, ROI)
    far = pose_to_matrix((60.0, 0.0, 0.0, 1.0), tr.center0)
    unique = Match(np.zeros(2), 0.9, 0.3)
    assert [tr._verified(far, unique) for _ in range(5)] == [False] * 4 + [True]
    # a seeded estimate is not this tracker's measurement: the usual confirmation over reacquire_frames
    seeded = make_tracker("hybrid", surroundings_veto_frames=5)
    seeded.init(img, ROI)
    seeded.seed(np.eye(3))
    n = seeded.hconfig.reacquire_frames
    assert [seeded._verified(far, unique) for _ in range(n)] == [False] * (n - 1) + [True]
    for bad in (-1, 2.5, True):
        with pytest.raises(ConfigError, match="surroundings_veto_frames"):
            make_tracker("hybrid", surroundings_veto_frames=bad)


def test_a_variants_surroundings_settings_stay_under_the_callers():
    # the variant's background_config (a dict) and the caller's are merged, as the LK's settings are
    bg = make_tracker("hybrid_similarity_chain", background_config={"hop": 3}).hconfig.background_config
    assert bg.hop == 3 and not bg.homography and not bg.occluder_prior and bg.cell_corners == 0
    assert make_tracker("hybrid", background_config={"cell_corners": 2}).hconfig.background_config.homography
    with pytest.raises(ConfigError, match="background_config"):
        make_tracker("hybrid_similarity_chain", background_config={"hops": 3})


@pytest.mark.parametrize("settings", [{}, {"warp": "homography"}, {"residual": True},
                                      {"warp": "homography", "occlusion_gate": 0.3, "margin": 6}])
def test_every_way_of_asking_for_a_hybrid_gives_the_same_tracker(settings):
    """The hybrid's defaults are built in one place (HybridConfig.for_warp): make_tracker, the registry and the
    config class agree."""
    from hvs_sim.tracking.hybrid import HybridConfig

    assert make_tracker("hybrid", **settings).hconfig == HybridConfig.for_warp(**settings)
    if not settings:
        assert HybridConfig() == HybridConfig.for_warp()
    with pytest.raises(ConfigError, match="unknown setting"):
        HybridConfig.for_warp(**settings, gate=0.4)


def test_an_alignment_may_continue_the_estimates_roll_when_its_seed_is_the_template_as_taken():
    # the global match's seed from the template as taken has θ = 0; a target seen rolled 7° (a camera off the goal
    # after an occlusion) is a jump from that seed, not from the estimate, which already has the roll
    import cv2

    img = _frame()
    tr = make_tracker("hybrid")
    tr.init(img, ROI)
    al, c = tr.aligner, tr.center0
    truth = pose_to_matrix((0.0, 0.0, np.radians(7.0), 1.0), c)
    frame = cv2.warpAffine(img, truth[:2], img.shape[1::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    work = al.work_image(frame)
    seed, estimate = al.to_work(np.eye(3)), al.to_work(pose_to_matrix((0.0, 0.0, np.radians(6.0), 1.0), c))
    assert al.config.max_rotation_step < np.radians(7.0)
    assert al.align(work, seed).A_work is None  # a roll step beyond max_rotation_step from the seed
    A = al.align(work, seed, estimate).A_work
    assert A is not None
    corners = tr.corners0
    assert np.abs(apply(al.to_full(A), corners) - apply(truth, corners)).max() < 0.3
    far = al.to_work(pose_to_matrix((0.0, 0.0, np.radians(-10.0), 1.0), c))  # neither the seed's nor this one
    assert al.align(work, seed, far).A_work is None
    # in a re-acquisition the last alignment's θ and s bound it too, a step per frame since: an estimate a skewed
    # surroundings measurement turned 17° away no longer refuses the target seen rolled 7° (HybridTracker._update)
    last = al.to_work(np.eye(3))  # aligned at θ = 0, 7° from the target now
    assert al.align(work, seed, far, aligned=(last, 1)).A_work is None  # one frame: 7° is more than a step
    A = al.align(work, seed, far, aligned=(last, 2)).A_work
    assert A is not None and np.abs(apply(al.to_full(A), corners) - apply(truth, corners)).max() < 0.3


def test_an_exposure_drift_does_not_move_the_feature_lk_on_a_low_contrast_target():
    """Hazy low-contrast texture over a brightness ramp (a sky's haze), seen 20 % darker or brighter: VGG features
    are not invariant to a gain, and the feature LK on the frame as it comes is pulled along the ramp; scaled to
    the template's exposure first (`normalise_lk_exposure`) it aligns."""
    import cv2

    ramp = (120 + 0.4 * np.arange(480, dtype=np.float32))[:, None, None]
    c = np.array([ROI[0] + (ROI[2] - 1) / 2, ROI[1] + (ROI[3] - 1) / 2])

    def error(method: str, img: np.ndarray, gain: float, dx: float, dy: float) -> tuple[str, float]:
        shifted = cv2.warpAffine(img.astype(np.float32) * gain, np.float32([[1, 0, dx], [0, 1, dy]]),
                                 img.shape[1::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        tr = make_tracker(method, allow_untrackable=True)
        tr.init(img, ROI)
        tk = tr.update(np.clip(shifted, 0, 255).astype(np.uint8))
        return tk.mode, float(np.linalg.norm(tk.center - (c + (dx, dy))))

    assert not make_tracker("hybrid_paper").aligner.config.normalise_lk_exposure  # the paper's LK: the frame as it comes
    raw = []
    for name, seed in (("foliage", 2), ("fabric", 1)):
        tex = _frame(name, seed).astype(np.float32)
        img = np.clip(ramp + 0.1 * (tex - tex.mean()), 0, 255).astype(np.uint8)
        for gain, (dx, dy) in itertools.product((0.8, 1.2), ((1.5, -1.0), (-2.5, 2.0))):
            mode, err = error("hybrid", img, gain, dx, dy)
            assert mode == "align" and err < 0.15, (name, gain, mode, err)
            raw.append(error("hybrid_raw_lk", img, gain, dx, dy))
    assert any(mode != "align" or err > 1.0 for mode, err in raw)  # as it comes, the drift stops or moves the LK


def test_the_feature_lk_under_the_targets_perspective_keeps_its_place_whichever_part_is_hidden():
    """A tilted target (corners 9 px from a similarity's): the similarity that fits it best sits at a place that
    depends on which part of it shows, so covering a side moves the alignment with no texture pulling it. Aligned as
    the similarity under the target's perspective (Aligner.shape: the correction less its own similarity), the centre
    stays on the target's whether all of it, its left or its right is seen."""
    import cv2

    from hvs_sim.tracking.aligner import Aligner
    from hvs_sim.tracking.hybrid_config import hybrid_deep_config
    from hvs_sim.tracking.warp import fit_similarity

    img = _frame("brick", 3)
    al = Aligner(hybrid_deep_config())
    al.set_template(img, ROI)
    c = np.array([ROI[0] + (ROI[2] - 1) / 2, ROI[1] + (ROI[3] - 1) / 2])

    def moved(v) -> np.ndarray:
        return np.array([[1, 0, v[0]], [0, 1, v[1]], [0, 0, 1.0]])

    H = moved(c + (1.5, -1.0)) @ np.array([[1, 0, 0], [0, 1, 0], [0.0015, 0.0009, 1.0]]) @ moved(-c)
    frame = cv2.warpPerspective(img, H, (640, 480), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    corners = np.array([[ROI[0], ROI[1]], [ROI[0] + ROI[2] - 1, ROI[1]], [ROI[0] + ROI[2] - 1, ROI[1] + ROI[3] - 1],
                        [ROI[0], ROI[1] + ROI[3] - 1]], float)
    seen = apply(H, corners)
    true_centre = apply(H, c[None])[0]
    C = np.linalg.solve(fit_similarity(corners, seen), H)  # the perspective (set_shape takes its similarity out)
    left, right = seen[:, 0].min(), seen[:, 0].max()
    errors = {None: [], "shape": []}
    for hidden in (None, slice(None, int(left + 0.35 * (right - left))), slice(int(left + 0.65 * (right - left)), None)):
        f = frame.copy()
        if hidden is not None:
            f[:, hidden] = 128
        work = al.work_image(f)
        for shape, found in errors.items():
            al.set_shape(None if shape is None else C)
            A = al.align(work, np.eye(3)).A_work
            assert A is not None
            A = al.to_full(A if shape is None else A @ al.shape)
            found.append(apply(A, c[None])[0] - true_centre)
    flat, shaped = np.array(errors[None]), np.array(errors["shape"])
    assert np.linalg.norm(shaped, axis=1).max() < 0.2, shaped
    assert np.linalg.norm(flat, axis=1).max() > 1.0, flat  # the similarity alone misses the tilted target's centre
    assert np.linalg.norm(flat - flat[0], axis=1).max() > 0.5, flat  # and by how much depends on what is hidden


def test_an_alignment_is_shown_clearly_only_by_about_what_tells_the_two_poses_apart():
    """Aligner.shows_clearly: the true pose against one 2.5 px off is shown clearly, and not the other way round. Two
    poses either side of the truth, neither right, the nearer fitting a little better: not by half the template's own
    difference between them (`hybrid_clear_pull`'s pull_evidence), though it fits better (evidence 0, the default)."""
    import cv2

    from hvs_sim.tracking.aligner import Aligner
    from hvs_sim.tracking.hybrid_config import hybrid_deep_config
    from hvs_sim.tracking.warp import similarity

    evidence = make_tracker("hybrid_clear_pull").hconfig.pull_evidence
    assert evidence == 0.5 and make_tracker("hybrid").hconfig.pull_evidence == 0.0
    for name in ("brick", "foliage"):
        img = _frame(name, 3)
        al = Aligner(hybrid_deep_config())
        al.set_template(img, ROI)
        frame = cv2.warpAffine(img, np.float32([[1, 0, 1.0], [0, 1, 0.5]]), (640, 480), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REFLECT)
        work = al.work_image(frame)

        def pose(dx: float, al: Aligner = al) -> np.ndarray:
            return al.to_work(similarity(dx, 0.5, 0.0, 1.0))

        assert al.shows_clearly(work, pose(1.0), pose(3.5), 0.9, evidence)
        assert not al.shows_clearly(work, pose(3.5), pose(1.0), 0.9, 0.0)
        near, far = pose(1.9), pose(-0.3)  # 0.9 and 1.3 px off
        assert al.shows_clearly(work, near, far, 0.9, 0.0) and not al.shows_clearly(work, near, far, 0.9, evidence)


def test_a_template_that_cannot_tell_two_poses_apart_shows_neither_clearly():
    """Aligner.shows_clearly with `discernible`: a template shading only downwards is the same 12 px to the side, so
    the frame cannot say which of two such poses is right, however their fits differ (a coat over more of one); a
    textured template tells them apart, and the right one is shown clearly."""
    from hvs_sim.tracking.aligner import Aligner
    from hvs_sim.tracking.hybrid_config import hybrid_deep_config
    from hvs_sim.tracking.warp import similarity

    rng = np.random.default_rng(5)
    x, y, w, h = ROI
    shaded = np.repeat(np.linspace(100, 140, 480, dtype=np.float32)[:, None], 640, 1)
    for base, flat in ((shaded, True), (_frame("brick", 3).astype(np.float32), False)):
        img = np.clip(base if base.ndim == 3 else np.dstack([base] * 3), 0, 255).astype(np.uint8)
        al = Aligner(hybrid_deep_config())
        al.set_template(img, ROI)
        frame = np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)
        coat = np.kron(rng.integers(20, 235, (h // 8 + 1, w // 8 + 1)), np.ones((8, 8)))[:h, :int(0.6 * w)]
        frame[y:y + h, x:x + int(0.6 * w)] = coat[..., None].astype(np.uint8)  # over 60 % of the true pose
        work = al.work_image(frame)
        true, aside = al.to_work(np.eye(3)), al.to_work(similarity(12.0, 0.0, 0.0, 1.0))
        if flat:  # the pose aside shows more of the (featureless) target, and fits better
            assert al.shows_clearly(work, aside, true, 0.5, 0.0)
            assert not al.shows_clearly(work, aside, true, 0.5, 0.0, discernible=True)
        else:
            assert al.shows_clearly(work, true, aside, 0.35, 0.0, discernible=True)
            assert not al.shows_clearly(work, aside, true, 0.35, 0.0, discernible=True)


@pytest.mark.parametrize("lookalike_drift", [True, False])
def test_with_a_look_alike_in_view_a_far_reacquisition_is_not_put_down_to_the_surroundings_drift(lookalike_drift,
                                                                                                  monkeypatch):
    """A static target hidden for 85 frames, every one measured on the surroundings: an alignment 37 px from their
    estimate, on a patch that looks like the target, where the match is not unique. The measured hops did not drift
    (HybridConfig.lookalike_drift): refused; only frames the predictor guessed allow reacquire_drift_px each."""
    img = _frame()
    tr = make_tracker("hybrid", target_motion="static", lookalike_drift=lookalike_drift)
    tr.init(img, ROI)
    assert tr.update(_shifted(img, 1.0, 0.5)).mode == "align"
    st = tr.state
    st.since_aligned, st.guessed, st.drift_run, st.scene_held = 85, 0, 0, True
    monkeypatch.setattr(tr, "_looks_like_target", lambda work, A: True)
    monkeypatch.setattr(tr, "_surroundings_agree", lambda A, work: False)
    far = pose_to_matrix((37.0, 0.0, 0.0, 1.0), st.center0) @ st.A
    work = tr.aligner.work_image(img)
    match = Match(center=np.zeros(2), score=0.9, second=0.88)
    assert tr._reacquisition_verified(far, match, work, unique=False) is not lookalike_drift
    st.guessed = 70  # the predictor guessed on most of the frames: the estimate may be that far off
    assert tr._reacquisition_verified(far, match, work, unique=False)


@pytest.mark.parametrize("lookalike_drift", [True, False])
def test_with_a_look_alike_in_view_a_near_jump_is_not_put_down_to_the_surroundings_drift(lookalike_drift,
                                                                                       monkeypatch):
    """The same within REACQUIRE_AFTER frames of the last alignment (no re-acquisition): 12 frames measured on the
    surroundings, an alignment 12.6 px from the estimate where the match is not unique (a person wearing the target's
    picture walked in over it). The flat allowance (8 px + 0.5 px a frame: 14 px) took it; with lookalike_drift the
    measured frames add nothing and it is refused, while a unique match or guessed frames still get the allowance."""
    img = _frame()
    tr = make_tracker("hybrid", target_motion="static", lookalike_drift=lookalike_drift)
    tr.init(img, ROI)
    assert tr.update(_shifted(img, 1.0, 0.5)).mode == "align"
    st = tr.state
    st.since_aligned, st.guessed, st.drift_run, st.predict_run, st.scene_held = 12, 0, 0, 0, True
    assert not tr._reacquiring()
    unique = {"now": False}
    monkeypatch.setattr(tr, "_unique", lambda A, m, work: unique["now"])
    monkeypatch.setattr(tr, "_surroundings_agree", lambda A, work: False)
    near = pose_to_matrix((12.6, 0.0, 0.0, 1.0), st.center0) @ st.A
    work = tr.aligner.work_image(img)
    match = Match(center=np.zeros(2), score=0.9, second=0.88)
    assert tr._verified(near, match, work) is not lookalike_drift
    st.guessed = 12  # every one of those frames guessed by the predictor: the estimate may be that far off
    assert tr._verified(near, match, work)
    st.guessed, unique["now"] = 0, True  # no look-alike in view: the allowance per frame since the alignment
    assert tr._verified(near, match, work)


def test_an_alignment_keeps_the_scale_the_surroundings_carried_over_a_few_frames():
    """HybridState.departs_in_scale (HybridConfig.carried_scale_step): after frames the surroundings alone carried the
    estimate, an alignment 5 % off its scale departs and 1 % does not; not on the frame after an alignment, after a
    predictor's guess, past `window` frames (a re-acquisition), or with the step 0 (`hybrid_free_scale`)."""
    from hvs_sim.tracking.sources import HybridState
    from hvs_sim.tracking.warp import similarity

    centre = np.array([320.0, 240.0])
    st = HybridState(center0=centre, corners0=np.zeros((4, 2)), A=similarity(3.0, -2.0, 0.01, 1.1),
                     keyframe=(np.zeros((4, 4)), np.eye(3)))

    def scaled(k: float) -> np.ndarray:  # the estimate's pose, its scale times k about the target's centre
        return st.A @ similarity(*(centre - k * centre), 0.0, k)

    step, window = make_tracker("hybrid").hconfig.carried_scale_step, 15
    assert step == 0.02 and make_tracker("hybrid_free_scale").hconfig.carried_scale_step == 0.0
    st.since_aligned = 2
    assert st.departs_in_scale(scaled(1.05), step, window) and st.departs_in_scale(scaled(0.95), step, window)
    assert not st.departs_in_scale(scaled(1.01), step, window)
    assert not st.departs_in_scale(scaled(1.05), 0.0, window)
    st.since_aligned = window
    assert not st.departs_in_scale(scaled(1.05), step, window)
    st.since_aligned, st.drift_run = 2, 1
    assert not st.departs_in_scale(scaled(1.05), step, window)
    st.since_aligned, st.drift_run = 0, 0
    assert not st.departs_in_scale(scaled(1.05), step, window)
