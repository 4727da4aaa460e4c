"""The homography's intensity refinement in the template's frame (tracking/intensity_ic.py)."""

import cv2
import numpy as np
import pytest
from photos import photo

from hvs_sim.tracking.ecc import ecc_template
from hvs_sim.tracking.frames import roi_corners
from hvs_sim.tracking.intensity_ic import IntensityIC
from hvs_sim.tracking.warp import apply

H, W = 480, 640
ROI = (250, 170, 120, 84)
CORNERS = roi_corners((0, 0, ROI[2], ROI[3]))
T = np.array([[1, 0, ROI[0]], [0, 1, ROI[1]], [0, 0, 1.0]])  # template px → first frame px


def grey(name):
    return cv2.cvtColor(photo(name), cv2.COLOR_RGB2GRAY)


def model(g, clip_aware=True):
    x, y, w, h = ROI
    return IntensityIC(ecc_template(g, ROI, 5), 5, g[y:y + h, x:x + w] if clip_aware else None)


def warped(g, k, amplitude=4.0):
    src = roi_corners(ROI).astype(np.float32)
    shift = np.random.default_rng([k, 11]).uniform(-amplitude, amplitude, (4, 2))
    Hm = cv2.getPerspectiveTransform(src, (src + shift).astype(np.float32))
    return cv2.warpPerspective(g, Hm, (W, H), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT), Hm @ T


def worst(Wa, Wb):
    return float(np.abs(apply(Wa, CORNERS) - apply(Wb, CORNERS)).max())


OFF = np.array([[1.002, 0, 0.8], [0, 0.998, -0.6], [0, 0, 1]])  # the start: ~1 px off at the corners


@pytest.mark.parametrize("name", ["china", "flower"])
def test_recovers_perspective_warps_of_photos_within_a_tenth_of_a_pixel(name):
    g = grey(name)
    ic = model(g)
    for k in range(3):
        frame, truth = warped(g, k)
        res = ic.align(frame, OFF @ truth)
        assert res is not None and res.converged and res.iterations < 15
        assert worst(res.warp, truth) < 0.1, (k, worst(res.warp, truth))


def test_from_the_truth_on_its_own_frame_it_stays_and_an_exposure_change_does_not_move_it():
    g = grey("flower")
    ic = model(g)
    assert worst(ic.align(g, T).warp, T) < 1e-3
    brighter = np.clip(0.8 * g.astype(float) + 20, 0, 255).astype(np.uint8)  # gain and offset, nothing clipped
    assert worst(ic.align(brighter, OFF @ T).warp, T) < 0.02


def test_clipped_pixels_are_left_out(monkeypatch):
    """A 1.4× gain clips the bright parts: they do not follow gain and offset, and left in they pull the warp."""
    import hvs_sim.tracking.intensity_ic as ic_module

    g = grey("china")
    frame, truth = warped(g, 1)
    over = np.clip(1.4 * frame.astype(float), 0, 255).astype(np.uint8)
    x, y, w, h = ROI
    assert np.mean(over[y:y + h, x:x + w] == 255) > 0.03
    aware = worst(model(g).align(over, OFF @ truth).warp, truth)
    monkeypatch.setattr(ic_module, "CLIP_LO", -1)
    monkeypatch.setattr(ic_module, "CLIP_HI", 256)  # no level counts as clipped
    naive = worst(model(g, clip_aware=False).align(over, OFF @ truth).warp, truth)
    # 44 % of this patch is clipped: what is left holds the warp to a fraction of a pixel, left in they pull it ~2 px
    assert aware < 0.25 and naive > 5 * aware, (aware, naive)


def test_an_occluder_is_left_out_by_the_seen_mask_and_too_little_gives_no_answer():
    g = grey("flower")
    ic = model(g)
    frame, truth = warped(g, 2)
    frame = frame.copy()
    x, y, w, h = ROI
    frame[y - 10:y + h + 10, x - 10:x + w // 3] = 30  # a dark body over the left third
    seen = np.ones((h, w), bool)
    seen[:, :w // 3 + 8] = False
    assert worst(ic.align(frame, OFF @ truth, seen).warp, truth) < 0.1
    none = np.zeros((h, w), bool)
    none[:5, :5] = True
    assert ic.align(frame, OFF @ truth, none) is None


def test_a_frame_without_texture_gives_no_answer():
    g = grey("flower")
    assert model(g).align(np.full((H, W), 128, np.uint8), T) is None


def test_smoothing_in_the_frame_as_ecc_does_is_the_hybrids_and_a_wrong_mode_is_refused():
    """smooth="frame" (ECC's model: smooth in the frame's pixels, resample bilinearly) also converges on a warped
    photo, less exactly than on the template's grid; the hybrid uses it, deep_lk the template's grid."""
    from hvs_sim.errors import ConfigError
    from hvs_sim.tracking import make_tracker

    g = grey("flower")
    x, y, w, h = ROI
    ic = IntensityIC(ecc_template(g, ROI, 5), 5, g[y:y + h, x:x + w], smooth="frame")
    for k in range(3):
        frame, truth = warped(g, k)
        res = ic.align(frame, OFF @ truth)
        assert res is not None and res.converged and worst(res.warp, truth) < 0.2, (k, res)
    assert make_tracker("hybrid", warp="homography").config.intensity_smooth == "frame"
    assert make_tracker("deep_lk", warp="homography").config.intensity_smooth == "template"
    with pytest.raises(ConfigError, match="smooth must be one of template, frame"):
        IntensityIC(ecc_template(g, ROI, 5), 5, smooth="both")
    with pytest.raises(ConfigError, match="intensity_smooth must be one of"):
        make_tracker("hybrid", warp="homography", intensity_smooth="both")


def test_the_3x3_update_inverse_matches_numpy_and_a_singular_one_gives_none():
    from hvs_sim.tracking.warp import inverse_3x3

    rng = np.random.default_rng(3)
    for _ in range(20):
        M = np.eye(3) + 0.2 * rng.standard_normal((3, 3))
        assert np.allclose(inverse_3x3(M), np.linalg.inv(M), atol=1e-12)
    assert inverse_3x3(np.ones((3, 3))) is None
    assert inverse_3x3(np.full((3, 3), np.nan)) is None


def test_frame_mode_gives_the_same_answer_for_a_uint8_and_a_float_frame_and_a_flat_template_gives_none():
    """smooth="frame" resamples the uint8 frame without a float copy: the same warp as from the float frame."""
    g = grey("flower")
    x, y, w, h = ROI
    ic = IntensityIC(ecc_template(g, ROI, 5), 5, g[y:y + h, x:x + w], smooth="frame")
    frame, truth = warped(g, 1)
    a, b = ic.align(frame, OFF @ truth), ic.align(frame.astype(np.float32), OFF @ truth)
    assert a is not None and b is not None and worst(a.warp, b.warp) < 1e-9 and a.iterations == b.iterations
    flat = np.full((H, W), 90, np.uint8)
    assert IntensityIC(ecc_template(flat, ROI, 5), 5).align(frame, T) is None  # no texture: no system to solve
