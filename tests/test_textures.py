"""Natural textures: shape, determinism, variety per seed, texture level, trackability ranking, bad input."""

import cv2
import numpy as np
import pytest

from hvs_sim.errors import HvsError
from hvs_sim.scene.textures import (
    NATURAL_TEXTURES,
    PHOTO_TEXTURES,
    PROCEDURAL_TEXTURES,
    TEXTURE_SETS,
    natural_texture,
    texture_set,
    trackability,
    write_contact_sheet,
)

SMALL = (96, 64)  # (width, height): non-square, so width/height mix-ups show
MIN_GREY_STD = 8.0  # the weakest texture (fine sand) has a grey std of ~10 at this size
LOW_TEXTURE_MAX = 2.5e-4  # trackability at 256 px of the low-texture set (sky, sand, wood grain)


def grey(img):
    return cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)


@pytest.mark.parametrize("name", NATURAL_TEXTURES)
def test_shape_dtype_and_determinism(name):
    a = natural_texture(name, *SMALL, seed=3)
    assert a.shape == (SMALL[1], SMALL[0], 3) and a.dtype == np.uint8
    assert np.array_equal(a, natural_texture(name, *SMALL, seed=3))
    assert not np.array_equal(a, natural_texture(name, *SMALL, seed=4))


@pytest.mark.parametrize("name", NATURAL_TEXTURES)
def test_not_flat(name):
    for seed in (0, 1):
        assert grey(natural_texture(name, *SMALL, seed=seed)).std() > MIN_GREY_STD, (name, seed)


def test_sets_partition_and_names():
    assert set(TEXTURE_SETS["natural"]) == set(NATURAL_TEXTURES)
    assert set(PROCEDURAL_TEXTURES) | set(PHOTO_TEXTURES) == set(NATURAL_TEXTURES)
    assert not set(PROCEDURAL_TEXTURES) & set(PHOTO_TEXTURES)
    for name, members in TEXTURE_SETS.items():
        assert members and set(members) <= set(NATURAL_TEXTURES), name
        assert texture_set(name) == members
    assert {"fur", "foliage", "brick", "gravel"} <= set(texture_set("self_similar"))
    assert len(PROCEDURAL_TEXTURES) >= 14 and len(PHOTO_TEXTURES) >= 4


def test_trackability_ranks_flat_below_clouds_below_brick_and_poster():
    flat = np.full((256, 256, 3), 128, np.uint8)
    assert trackability(flat) == pytest.approx(0.0, abs=1e-12)
    for seed in (0, 1, 2):
        clouds = trackability(natural_texture("clouds", 256, 256, seed))
        assert 0.0 < clouds < LOW_TEXTURE_MAX
        for rich in ("brick", "poster"):
            assert trackability(natural_texture(rich, 256, 256, seed)) > 2 * clouds, (rich, seed)


def test_low_texture_set_is_less_trackable_than_self_similar_set():
    low = max(trackability(natural_texture(n, 256, 256, 0)) for n in texture_set("low_texture"))
    rich = min(trackability(natural_texture(n, 256, 256, 0)) for n in texture_set("self_similar"))
    assert low < LOW_TEXTURE_MAX < rich


def test_trackability_sees_the_aperture_problem_and_accepts_grey_float():
    ys, xs = np.mgrid[0:128, 0:128].astype(np.float32)
    stripes = 0.5 + 0.4 * np.sin(xs / 3.0)  # strong gradients, all in x
    assert trackability(stripes) < 1e-6
    checker = 0.5 + 0.4 * np.sin(xs / 3.0) * np.sin(ys / 3.0)
    assert trackability(checker) > 1e-3
    img = natural_texture("gravel", 128, 128)
    assert trackability(grey(img) / 255.0) == pytest.approx(trackability(img), rel=0.05)


@pytest.mark.parametrize("name", PHOTO_TEXTURES)
def test_photo_crops_differ_per_seed(name):
    crops = [natural_texture(name, 64, 48, seed).astype(np.float32) for seed in range(4)]
    for i in range(len(crops)):
        for j in range(i + 1, len(crops)):
            assert np.abs(crops[i] - crops[j]).mean() > 3.0, (name, i, j)


def test_bad_name_size_and_seed_raise_hvs_error():
    with pytest.raises(HvsError, match="unknown texture 'velvet'.*wood"):
        natural_texture("velvet")
    with pytest.raises(HvsError, match="unknown texture set"):
        texture_set("nope")
    for bad in (0, 31, 5000, 64.0, True, "64", None):
        with pytest.raises(HvsError, match="width must be an integer in"):
            natural_texture("wood", width=bad)
        with pytest.raises(HvsError, match="height must be an integer in"):
            natural_texture("wood", height=bad)
    for bad in (-1, 1.5, "0"):
        with pytest.raises(HvsError, match="seed must be an integer"):
            natural_texture("wood", seed=bad)


def test_contact_sheet(tmp_path):
    path = write_contact_sheet(tmp_path / "sheet.png", names=["brick", "photo_aero"], seeds=(0, 1, 2), size=48)
    sheet = cv2.imread(str(path))
    assert sheet is not None and sheet.shape[1] == 6 * 48 and sheet.shape[0] > 48
