"""People in front of the target: plain figures unchanged, textured ones seeded, clothed and in bounds."""

from __future__ import annotations

from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest
from dm_control import mjcf
from dm_control.mujoco.wrapper import core as mj_core

from hvs_sim.errors import HvsError
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene import CameraConfig, make_scenario
from hvs_sim.scene.people import (
    BOTTOMS,
    FABRIC_KINDS,
    HAIR_STYLES,
    OCCLUDER_GROUP,
    PERSON_STYLES,
    TOPS,
    Person,
    fabric_colours_needed,
    fabric_texture,
)
from hvs_sim.scene.scenarios import PEOPLE_STYLES
from hvs_sim.scene.world import Scene

DATA = Path(__file__).parent / "data"
CLOSE_FRAME = 86  # hand-held walk_by, seed 0: the person fills most of the view
MARGIN = 0.01  # m of slack on HALF_WIDTH / HALF_DEPTH (the plain figure's hands stick out 5 mm)
TARGET_BAND = (1.25, 1.35)  # heights at which the line of sight to the target crosses a person
ANKLE_Z = 0.15  # below this, shoes may stick forward like the plain figure's (toe at 0.16 m)...
TOE_X = 0.17  # ... but no further than this


def _scene_at(frame: int, **kw) -> Scene:
    scene = Scene(make_scenario("walk_by", **kw))
    for _ in range(frame):
        scene.advance()
    return scene


@pytest.mark.parametrize("mount", ["handheld", "arm"])
def test_plain_people_reproduce_the_golden_frames_bit_for_bit(mount):
    # the golden frames were rendered with 4× multisampling, the default of the time
    scene = _scene_at(81, mount=mount, seed=3, camera=CameraConfig(width=320, height=240, multisample=4), people="plain")
    golden = cv2.imread(str(DATA / f"golden_walk_by_{mount}_f81.png"))[..., ::-1]
    assert np.array_equal(Renderer(scene).rgb(), golden)


def _plain_draws(rng: np.random.Generator) -> None:
    """The four draws the original Person made, in order."""
    rng.uniform(0.1, 0.9, 3), rng.uniform(0.05, 0.4, 3), rng.uniform(0.55, 1.0), rng.uniform(0.05, 0.3)


@pytest.mark.parametrize("style", PERSON_STYLES)
def test_styles_take_the_plain_draws_first(style):
    """Plain takes exactly the original draws; textured the same, then one integer for its own generator."""
    rng, expected = np.random.default_rng(11), np.random.default_rng(11)
    Person(mjcf.RootElement(), 0, rng, style=style)
    _plain_draws(expected)
    if style == "textured":
        expected.integers(2 ** 63)
    assert rng.bit_generator.state == expected.bit_generator.state


def test_textured_look_depends_only_on_seed_and_index():
    outfits = [[p.outfit for p in Scene(make_scenario("two_people", seed=s)).people] for s in (4, 4, 5)]
    assert outfits[0] == outfits[1]
    assert outfits[0][0] != outfits[0][1]  # two people in one scene dress differently
    assert outfits[0][0] != outfits[2][0] and outfits[0][1] != outfits[2][1]


def test_textured_people_render_the_same_for_the_same_seed_and_differently_for_another():
    small = CameraConfig(width=160, height=120)
    frames = [Renderer(_scene_at(CLOSE_FRAME, seed=s, camera=small)).rgb() for s in (2, 2, 9)]
    assert np.array_equal(frames[0], frames[1])
    assert not np.array_equal(frames[0], frames[2])


def _person_pixels(renderer: Renderer) -> np.ndarray:
    """Pixels that show a person geom, away from the edges between geoms (segmentation render)."""
    scene = renderer.scene
    show_people = mj_core.MjvOption()
    show_people.geomgroup[OCCLUDER_GROUP] = 1
    seg = scene.physics.render(renderer.height, renderer.width, camera_id=scene.physics.bind(scene.camera).element_id,
                               segmentation=True, scene_option=show_people)
    ids = seg[..., 0].astype(np.float32)
    is_geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
    person = is_geom & (scene.physics.model.geom_group[np.clip(seg[..., 0], 0, None)] == OCCLUDER_GROUP)
    kernel = np.ones((7, 7), np.uint8)
    return person & (cv2.erode(ids, kernel) == cv2.dilate(ids, kernel))


def _local_std(rgb: np.ndarray) -> np.ndarray:
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
    mean, mean_sq = cv2.blur(grey, (5, 5)), cv2.blur(grey * grey, (5, 5))
    return np.sqrt(np.maximum(mean_sq - mean * mean, 0.0))


def test_a_close_textured_person_shows_cloth_texture_not_a_flat_slab():
    texture = {}
    for style in ("plain", "textured"):
        renderer = Renderer(_scene_at(CLOSE_FRAME, seed=0, people=style))
        assert renderer.ground_truth().occlusion > 0.9
        pixels = _person_pixels(renderer)
        assert pixels.mean() > 0.4  # the person fills much of the view
        texture[style] = float(np.median(_local_std(renderer.rgb())[pixels]))
    assert texture["textured"] > 2.5, texture  # grey levels of 5x5 local spread
    assert texture["textured"] > 5 * texture["plain"], texture


def _person_vertices(physics, body) -> np.ndarray:
    """All mesh vertices of a person's geoms in its body frame (textured people are all meshes)."""
    m = physics.model
    body_id = m.name2id(body.name, "body")
    out = []
    for g in np.flatnonzero(m.geom_bodyid == body_id):
        assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
        assert (m.geom_contype[g], m.geom_conaffinity[g], m.geom_group[g]) == (0, 0, OCCLUDER_GROUP)
        mesh = m.geom_dataid[g]
        v = m.mesh_vert[m.mesh_vertadr[mesh]: m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, m.geom_quat[g])
        out.append(v @ rot.reshape(3, 3).T + m.geom_pos[g])
    return np.concatenate(out)


def test_textured_bodies_have_the_half_width_and_half_depth_the_planning_assumes():
    """Rule: every vertex has |y| <= HALF_WIDTH + 1 cm; above the ankles |x| <= HALF_DEPTH + 1 cm; the shoes
    (below 0.15 m) reach back no further than that and forward to at most 0.17 m. Where the line of sight to
    the target crosses the body (1.25-1.35 m) the silhouette reaches within 1 cm of HALF_WIDTH (sleeves, seen
    from the front) and 1.5 cm of HALF_DEPTH (chest, in profile). 1.75-1.82 m tall, standing on the floor."""
    root = mjcf.RootElement()
    people = [Person(root, k, np.random.default_rng([k, 3])) for k in range(16)]
    seen = {(p.outfit.top, p.outfit.bottom, p.outfit.hair_style) for p in people}
    assert {t for t, _, _ in seen} == set(TOPS) and {b for _, b, _ in seen} == set(BOTTOMS)
    assert {h for _, _, h in seen} == set(HAIR_STYLES)
    physics = mjcf.Physics.from_mjcf_model(root)
    for p in people:
        v = _person_vertices(physics, p.body)
        x, y, z = v.T
        assert np.abs(y).max() <= Person.HALF_WIDTH + MARGIN, p.outfit
        above = z > ANKLE_Z
        assert np.abs(x[above]).max() <= Person.HALF_DEPTH + MARGIN, p.outfit
        assert x[~above].min() >= -Person.HALF_DEPTH - MARGIN and x[~above].max() <= TOE_X, p.outfit
        band = (z > TARGET_BAND[0]) & (z < TARGET_BAND[1])
        assert np.abs(y[band]).max() >= Person.HALF_WIDTH - MARGIN, p.outfit
        assert np.abs(x[band]).max() >= Person.HALF_DEPTH - 1.5 * MARGIN, p.outfit
        assert 1.75 <= z.max() <= 1.82 and -1e-6 <= z.min() <= 0.005, p.outfit


def test_a_hovering_textured_person_covers_the_planned_share_of_the_target():
    """`partial` plans the occlusion from HALF_WIDTH: the textured body must cover what the plain one did."""
    occlusion = {}
    for style in ("plain", "textured"):
        scene = Scene(make_scenario("partial", seed=1, people=style, camera=CameraConfig(width=160, height=120)))
        renderer, occlusion[style] = Renderer(scene), []
        for frame in range(30, 150):
            if frame % 20 == 0:
                occlusion[style].append(renderer.ground_truth().occlusion)
            scene.advance()
    assert np.abs(np.subtract(occlusion["textured"], occlusion["plain"])).max() < 0.05, occlusion


@pytest.mark.parametrize("kind", FABRIC_KINDS)
def test_fabric_textures_are_seeded_rgb_tiles_that_wrap_seamlessly(kind):
    palette = [(200, 40, 50), (30, 40, 80), (240, 240, 230), (240, 200, 60), (60, 130, 70)]
    colours = palette[: max(3, fabric_colours_needed(kind))]
    img = fabric_texture(kind, colours, seed=7, size=128)
    assert img.shape == (128, 128, 3) and img.dtype == np.uint8
    assert np.array_equal(img, fabric_texture(kind, colours, seed=7, size=128))
    assert img.astype(float).std() > 3  # not a flat colour
    f = img.astype(float)
    for axis in (0, 1):  # the wrap is no more of an edge than the sharpest line-to-line step inside the tile
        other = 1 - axis
        inside = np.abs(np.diff(f, axis=axis)).mean(axis=(other, 2)).max()
        across = np.abs(np.take(f, 0, axis=axis) - np.take(f, -1, axis=axis)).mean()
        assert across <= 1.25 * inside + 1, (kind, axis, across, inside)


def test_bad_people_and_fabric_settings_raise_hvs_errors():
    assert PEOPLE_STYLES == PERSON_STYLES
    with pytest.raises(HvsError, match="person style"):
        Person(mjcf.RootElement(), 0, np.random.default_rng(0), style="cartoon")
    with pytest.raises(HvsError, match="people style"):
        make_scenario("walk_by", people="cartoon")
    with pytest.raises(HvsError, match="fabric"):
        fabric_texture("leather", [(1, 2, 3)], seed=0)
    with pytest.raises(HvsError, match="colours"):
        fabric_texture("floral", [(1, 2, 3)], seed=0)
    with pytest.raises(HvsError, match="size"):
        fabric_texture("denim", [(1, 2, 3), (4, 5, 6)], seed=0, size=100)
