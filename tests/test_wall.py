"""Targets and walls from any image: the user's file on the target, natural textures beside it, clear errors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from hvs_sim.cli import main
from hvs_sim.errors import HvsError
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene import wall as wall_module
from hvs_sim.scene.scenarios import SCENARIO_NAMES, WALL_SETS, make_scenario
from hvs_sim.scene.wall import wall_pictures
from hvs_sim.scene.world import Scene


def _poster(w: int = 400, h: int = 250, seed: int = 0) -> np.ndarray:
    """A procedural picture with texture at several scales (BGR, as cv2 writes it)."""
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    for cell in (40, 12, 4):
        small = rng.uniform(0, 1, (h // cell + 2, w // cell + 2, 3)).astype(np.float32)
        img += cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)[:h, :w]
    img = (img - img.min()) / (img.max() - img.min())
    return np.round(255 * img).astype(np.uint8)


@pytest.fixture
def poster_file(tmp_path):
    path = tmp_path / "poster.jpg"
    cv2.imwrite(str(path), _poster(), [cv2.IMWRITE_JPEG_QUALITY, 95])
    return path


def test_target_image_is_on_the_target_with_its_aspect_and_centre(poster_file):
    sc = make_scenario("clear", seed=0, target_image=str(poster_file), target_width=0.2, shake=0.0)
    r = Renderer(Scene(sc))
    gt = r.ground_truth()
    mask = r.target_mask()
    ys, xs = np.nonzero(mask)
    assert abs(xs.mean() - gt.center[0]) <= 0.5 and abs(ys.mean() - gt.center[1]) <= 0.5
    width = np.linalg.norm(gt.corners[1] - gt.corners[0])
    height = np.linalg.norm(gt.corners[3] - gt.corners[0])
    assert height / width == pytest.approx(250 / 400, rel=0.02)  # aspect ratio kept
    # the picture itself: the target region, rectified, matches the file
    H = cv2.getPerspectiveTransform(gt.corners.astype(np.float32) + 0.5,
                                    np.float32([[0, 0], [400, 0], [400, 250], [0, 250]]))
    seen = cv2.warpPerspective(r.rgb(), H, (400, 250))
    want = cv2.cvtColor(cv2.imread(str(poster_file)), cv2.COLOR_BGR2RGB)
    a, b = (cv2.GaussianBlur(cv2.cvtColor(x, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0), 3)[10:-10, 10:-10]
            for x in (seen, want))
    ncc = np.corrcoef(a.ravel(), b.ravel())[0, 1]
    assert ncc > 0.8


def test_bad_target_and_wall_inputs_are_clear_errors(tmp_path):
    with pytest.raises(HvsError, match="does not exist"):
        make_scenario("clear", target_image=str(tmp_path / "missing.png"))
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"not an image")
    with pytest.raises(HvsError, match="cannot read"):
        Scene(make_scenario("clear", target_image=str(garbage)))
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), np.zeros((20, 30, 3), np.uint8))
    with pytest.raises(HvsError, match="too small to track"):
        Scene(make_scenario("clear", target_image=str(tiny)))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(HvsError, match="holds no images"):
        Scene(make_scenario("clear", wall_images=str(empty)))
    with pytest.raises(HvsError, match="accepted"):
        make_scenario("clear", wall="posters")
    with pytest.raises(HvsError, match="not both"):
        make_scenario("clear", target_texture="wood", target_image=str(garbage))
    with pytest.raises(HvsError, match="target_width"):
        make_scenario("clear", target_width=3.0)
    with pytest.raises(HvsError, match="not both"):
        make_scenario("clear", wall="natural", wall_images=str(empty))
    ribbon = tmp_path / "ribbon.png"
    cv2.imwrite(str(ribbon), _poster(50, 400))
    with pytest.raises(HvsError, match="aspect"):
        Scene(make_scenario("clear", target_image=str(ribbon)))
    tall = tmp_path / "tall.png"
    cv2.imwrite(str(tall), _poster(100, 300))
    with pytest.raises(HvsError, match="tall"):
        Scene(make_scenario("clear", target_image=str(tall), target_width=0.5))
    (tmp_path / "thin").mkdir()  # 3000×80 shrinks to 1024×27: the size check comes after shrinking
    cv2.imwrite(str(tmp_path / "thin" / "a.png"), np.zeros((80, 3000, 3), np.uint8))
    with pytest.raises(HvsError, match="too small"):
        Scene(make_scenario("clear", wall_images=str(tmp_path / "thin")))


def test_wall_images_fill_the_slots(tmp_path):
    folder = tmp_path / "wall"
    folder.mkdir()
    for k in range(3):
        cv2.imwrite(str(folder / f"{k}.png"), _poster(300, 300, seed=k))
    target, others = wall_pictures(make_scenario("clear", wall_images=str(folder)))
    assert target == "star_field" and len(others) == 14
    assert all(o.shape[0] * 3 == o.shape[1] * 2 for o in others)  # cropped to the slots' 3:2
    assert np.array_equal(others[0], others[3]) and not np.array_equal(others[0], others[1])  # cycled in name order


@pytest.mark.parametrize("wall", [w for w in WALL_SETS if w != "flags"])
def test_texture_walls_are_seeded(wall):
    def pictures(seed):
        wall_module._texture.cache_clear()  # regenerate, so equality means the same seed gave the same texture
        return wall_pictures(make_scenario("clear", seed=seed, wall=wall))[1]

    a, b, c = pictures(3), pictures(3), pictures(4)
    assert len(a) == 14 and all(np.array_equal(x, y) for x, y in zip(a, b) if not isinstance(x, str))
    assert any(not isinstance(x, str) and not np.array_equal(x, y) for x, y in zip(a, c))


def test_presets_name_their_target_and_wall():
    sc = make_scenario("photo_pause")
    assert sc.target_texture == "photo_flower" and sc.wall == "printed"
    assert "poster_walk_by" in SCENARIO_NAMES
    frame = Renderer(Scene(make_scenario("poster_walk_by", camera=make_scenario("clear").camera))).rgb()
    assert frame.std() > 20


def test_scenes_list_and_cli_target_image(tmp_path, poster_file, capsys):
    assert main(["scenes", "--list"]) == 0
    out = capsys.readouterr().out
    for word in ("photo_pause", "phone_handheld", "self_similar", "--target-image"):
        assert word in out
    assert main(["scene", "--scenario", "clear", "--frames", "2", "--format", "png", "--target-image", str(poster_file),
                 "--camera", "webcam", "--out", str(tmp_path / "s")]) == 0
    assert main(["scene", "--scenario", "clear", "--frames", "2", "--target-image", str(tmp_path / "nope.png"),
                 "--out", str(tmp_path / "t")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["scene", "--scenario", "clear", "--frames", "2", "--target", "nope", "--out", str(tmp_path / "u")]) == 2
    assert "natural texture" in capsys.readouterr().err


def test_cli_target_and_wall_options_replace_the_presets(poster_file):
    """What the user names wins over the preset's target and wall, whatever kind they were."""
    import argparse

    from hvs_sim.cli import _scenario_from_args, build_parser

    def scenario(*argv) -> object:
        args = build_parser().parse_args(["scene", "--scenario", "photo_pause", *argv])
        assert isinstance(args, argparse.Namespace)
        return _scenario_from_args(args)

    assert scenario().target_label == "photo_flower"
    assert scenario().people == "textured" and scenario("--people", "plain").people == "plain"
    sc = scenario("--target", "star_field")
    assert (sc.target_flag, sc.target_texture, sc.target_image) == ("star_field", None, None)
    sc = scenario("--target-image", str(poster_file))
    assert (sc.target_texture, sc.target_image) == (None, str(poster_file))
    sc = scenario("--wall-images", str(poster_file.parent))
    assert (sc.wall, sc.wall_images) == ("flags", str(poster_file.parent))
    with pytest.raises(HvsError, match="not both"):
        scenario("--target", "wood", "--target-image", str(poster_file))
