"""The person in the scene: body geometry, the textured `Person` (dressed by `_Tailor` from an `Outfit`) and
the original plain figure, added to an MJCF model as mocap bodies in OCCLUDER_GROUP.
"""

from __future__ import annotations

import cv2
import numpy as np
from dm_control import mjcf

from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.scene.people.fabrics import hair_texture, skin_texture
from hvs_sim.scene.people.meshes import (
    CAP_RINGS,
    MeshData,
    Tube,
    _bump,
    ellipsoid_mesh,
    fold_gains,
    merge_meshes,
    tube_mesh,
)
from hvs_sim.scene.people.outfits import RGB, TOPS, Fabric, Outfit, _colour

OCCLUDER_GROUP = 3  # geom group of people, so that renders can hide them
PERSON_STYLES = ("textured", "plain")

# ------------------------------------------------------------------------------------------------
# Body geometry, metres in the person's frame: origin on the floor between the feet, +X forward,
# +Y to the left, +Z up; 1.8 m tall with hair. Arms and legs are given for the left side and mirrored.

# clothed torso from the neckline down: (z, x of the centre line, half depth, half width)
TORSO_PROFILE = (
    (1.515, -0.010, 0.050, 0.062),  # neckline
    (1.500, -0.012, 0.062, 0.100),  # base of the neck
    (1.475, -0.012, 0.074, 0.152),  # slope of the shoulders
    (1.440, -0.008, 0.086, 0.186),  # shoulder line
    (1.380, -0.002, 0.098, 0.180),  # armpits
    (1.300, 0.004, 0.104, 0.172),  # chest: with a jacket's ease its front is at HALF_DEPTH
    (1.200, 0.002, 0.098, 0.160),  # ribs
    (1.100, 0.000, 0.092, 0.152),  # waist
    (1.000, -0.004, 0.096, 0.160),  # hips
)
HEM_FLARE = 0.004  # a hem stands a little off the body
TORSO_SQUARENESS = 2.6  # between an ellipse and a rounded box: a chest seen from above
PELVIS = ((1.05, 0.000, 0.090, 0.148), (0.97, -0.004, 0.096, 0.158), (0.89, -0.008, 0.096, 0.158),
          (0.83, -0.004, 0.078, 0.122))
SKIRT = ((1.05, 0.000, 0.090, 0.148), (0.97, -0.004, 0.098, 0.162), (0.85, -0.004, 0.104, 0.180))
SKIRT_HEM_SIZE = (0.108, 0.205)
# shoulder, upper arm, elbow, forearm, wrist: hanging a little away from the body, so that the sleeves'
# outer edges at the target's height (~1.3 m) are at HALF_WIDTH, as the occlusion planning assumes
ARM_KNOTS = ((0.000, 0.205, 1.405), (-0.012, 0.228, 1.300), (-0.022, 0.224, 1.165), (0.000, 0.228, 1.030),
             (0.032, 0.232, 0.905))
SLEEVE_RADII = (0.054, 0.049, 0.045, 0.043, 0.039)
ARM_RADII = (0.046, 0.041, 0.036, 0.035, 0.028)
ARM_FLATTEN = 0.93  # arms and sleeves are a little narrower side to side than front to back
SHORT_SLEEVE = 0.4  # a T-shirt sleeve ends this far from the upper-arm knot towards the elbow
SHORT_SLEEVE_RADII = (0.056, 0.054, 0.053)
LEG_KNOTS = ((0.000, 0.088, 0.930), (0.004, 0.090, 0.720), (0.010, 0.092, 0.500), (0.002, 0.094, 0.320),
             (-0.004, 0.095, 0.060))  # hip, thigh, knee, calf, ankle (the hem covers the top of the shoe)
TROUSER_RADII = (0.086, 0.072, 0.058, 0.058, 0.055)
JEANS_RADII = (0.084, 0.068, 0.053, 0.052, 0.048)
BARE_LEG_RADII = (0.076, 0.062, 0.047, 0.052, 0.034)
NECK = ((0.0, 0.0, 1.47), (0.012, 0.0, 1.60), 0.05)  # from, to, radius
HEAD_CENTRE, HEAD_SIZE = np.array([0.012, 0.0, 1.672]), np.array([0.096, 0.077, 0.112])
HAIR_PIECES = (((0.0, 0.0, 1.725), (0.102, 0.084, 0.075)),  # crown: its front edge is the hairline, above the brows
               ((-0.03, 0.0, 1.68), (0.088, 0.084, 0.095)))  # back of the head, down to the nape
HAIR_BUZZ_SCALE = 0.975  # a buzz cut hugs the head
# shoe upper (heel, ball, toe) knots with (vertical, lateral) half sizes, and the sole from heel to toe
SHOE_UPPER = (((-0.07, 0.05), (0.042, 0.037)), ((0.02, 0.047), (0.04, 0.044)), ((0.105, 0.034), (0.026, 0.04)))
SOLE = ((-0.095, 0.14), 0.011, 0.047)  # (x from, x to), half thickness, half width
COLLARS = {  # (x, z, half depth, half width) at the top and the bottom of the collar band
    "shirt": ((-0.02, 1.57, 0.056, 0.061), (-0.01, 1.505, 0.064, 0.074)),
    "jacket": ((-0.016, 1.56, 0.06, 0.066), (-0.01, 1.5, 0.068, 0.08)),
}
CREW_NECK = ((-0.01, 1.535, 0.056, 0.062), (-0.01, 1.505, 0.06, 0.068))
BUTTON_PITCH, BUTTON_SIZE = 0.085, (0.0025, 0.006, 0.006)
ZIP_RADIUS, CORD_RADIUS, CORD_Y, CORD_Z = 0.0035, 0.004, 0.032, (1.47, 1.33)
HOOD = ((-0.07, 0.0, 1.515), (0.05, 0.12, 0.065))  # a hood lying down behind the neck
POCKET_Z, POCKET_SIZE = 1.08, (0.02, 0.1, 0.055)  # a hoodie's front pocket
# face features on the head ellipsoid: ((y, z, depth out of its surface), half sizes); mirrored ones at +y
NOSE = ((0.0, 1.655, -0.004), (0.016, 0.011, 0.026))
LIPS = ((0.0, 1.618, -0.002), (0.004, 0.019, 0.0045))
EYE = ((0.032, 1.684, -0.003), (0.004, 0.013, 0.0075))
IRIS_RADIUS, IRIS_FORWARD = 0.0055, 0.0028
BROW = ((0.033, 1.703, -0.001), (0.004, 0.019, 0.0045))
EAR = ((0.004, 0.076, 1.668), (0.012, 0.008, 0.028))  # centre in the body frame, half sizes
LONG_HAIR = ((-0.06, 0.0, 1.58), (0.05, 0.085, 0.14))
BUN = ((-0.07, 0.0, 1.76), (0.04, 0.04, 0.04))
# hand below the wrist: palm (offset, half sizes); thumb from, to (offsets, y towards the body) and radius
PALM = ((0.006, 0.0, -0.072), (0.04, 0.018, 0.068))
THUMB = ((0.026, -0.012, -0.03), (0.05, -0.014, -0.068), 0.011)
# cloth folds: (amplitude as a share of the radius, whole waves around, waves along, where they gather)
TORSO_DRAPE = ((3, 8), (0.5, 2.0), lambda n: 0.25 + 0.75 * np.linspace(0, 1, n))  # amplitude from TOPS
SLEEVE_FOLDS = (0.05, (1, 3), (3.0, 7.0), lambda n: 0.15 + _bump(n, 0.55, 0.14) + 0.6 * _bump(n, 1.0, 0.1))
SHORT_SLEEVE_FOLDS = (0.02, (1, 3), (1.0, 2.0), lambda n: np.linspace(0.3, 1.0, n))
TROUSER_FOLDS = (0.03, (1, 3), (3.0, 6.0), lambda n: 0.2 + _bump(n, 0.5, 0.12) + _bump(n, 1.0, 0.1))  # knees, hems
SKIRT_FOLDS = (0.04, (5, 9), (0.2, 0.8), lambda n: np.linspace(0, 1, n))  # pleats opening towards the hem
LIP_SHADE = 0.78  # lips are the skin tone, darker
SCLERA_RGB, IRIS_RGB, ZIP_RGB = (232, 228, 222), (36, 26, 20), (150, 150, 152)
SKIN_TILE_M, HAIR_TILE_M = 0.1, 0.08
# (around, along) mesh resolution of each part: enough for smooth shading at 0.3 m, no more
DETAIL = {
    "torso": (32, 26), "sleeve": (16, 20), "short_sleeve": (16, 6), "arm": (10, 12), "pelvis": (28, 6),
    "skirt": (28, 10), "leg": (14, 16), "collar": (20, 2), "head": (18, 10), "hair": (16, 8), "hand": (8, 5),
    "feature": (6, 4), "rod": (6, 2), "shoe": (10, 5),
}
# (specular, shininess) of the materials: cloth is matte, skin a little glossy, shoes polished
MATTE, SKIN_SHINE, HAIR_SHINE, POLISH = (0.04, 0.05), (0.12, 0.25), (0.22, 0.35), (0.35, 0.5)


def _mirror(points, side: int) -> tuple:
    return tuple((x, side * y, z) for x, y, z in points)


class Person:
    """A person on a mocap body (kinematic, no collisions), all geoms in OCCLUDER_GROUP.

    Body frame: origin on the floor between the feet, +X the walking direction, +Z up.
    style "plain": the original flat-coloured capsules and boxes, built from four draws of `rng`.
    style "textured": a clothed body; it makes the same four draws, then one integer that seeds its
    own generator, so its look depends only on the scenario seed and `index`.
    """

    HALF_DEPTH = 0.12  # half extent front to back: what the camera sees while it walks past in profile
    HALF_WIDTH = 0.28  # half extent shoulder to shoulder, arms included: what it sees when facing the camera

    def __init__(self, root: mjcf.RootElement, index: int, rng: np.random.Generator, style: str = "textured"):
        if style not in PERSON_STYLES:
            raise choice_error("person style", style, PERSON_STYLES)
        shirt = np.r_[rng.uniform(0.1, 0.9, 3), 1.0]
        trousers = np.r_[rng.uniform(0.05, 0.4, 3), 1.0]
        skin = np.r_[np.array([0.85, 0.65, 0.5]) * rng.uniform(0.55, 1.0), 1.0]
        hair = np.r_[rng.uniform(0.05, 0.3) * np.ones(3), 1.0]
        self.style = style
        self.body = root.worldbody.add("body", name=f"person{index}", mocap=True)
        self.outfit: Outfit | None = None
        if style == "plain":
            _build_plain(self.body, shirt, trousers, skin, hair, self.HALF_DEPTH)
            return
        own = np.random.default_rng([int(rng.integers(2 ** 63)), 17, index])
        self.outfit = Outfit.sample(own)
        _Tailor(root, self.body, f"person{index}", own).dress(self.outfit)


def _build_plain(body, shirt, trousers, skin, hair, half_depth: float) -> None:
    """The original figure: flat-coloured capsules, spheres and a box torso."""
    common = {"contype": 0, "conaffinity": 0, "group": OCCLUDER_GROUP}
    for side in (1, -1):
        body.add("geom", type="capsule", fromto=[0, side * 0.09, 0.07, 0, side * 0.09, 0.9], size=[0.065],
                 rgba=trousers, **common)
        body.add("geom", type="box", pos=[0.04, side * 0.09, 0.03], size=[0.12, 0.05, 0.03], rgba=[0.1, 0.1, 0.1, 1],
                 **common)
        body.add("geom", type="capsule", fromto=[0, side * 0.235, 1.47, 0.03, side * 0.235, 0.95], size=[0.045],
                 rgba=shirt, **common)
        body.add("geom", type="sphere", pos=[0.035, side * 0.235, 0.88], size=[0.05], rgba=skin, **common)
    body.add("geom", type="box", pos=[0, 0, 1.22], size=[half_depth, 0.19, 0.30], rgba=shirt, **common)
    body.add("geom", type="capsule", fromto=[0, 0, 1.5, 0, 0, 1.6], size=[0.05], rgba=skin, **common)
    body.add("geom", type="sphere", pos=[0.01, 0, 1.7], size=[0.105], rgba=skin, **common)
    body.add("geom", type="ellipsoid", pos=[-0.015, 0, 1.75], size=[0.1, 0.1, 0.07], rgba=hair, **common)


class _Tailor:
    """Builds one textured person: parts are meshed per material, then added as one geom each."""

    def __init__(self, root: mjcf.RootElement, body, prefix: str, rng: np.random.Generator):
        self.root, self.body, self.prefix, self.rng = root, body, prefix, rng
        self.materials: dict[str, tuple] = {}  # key: (material element, texture tile in metres)
        self.parts: dict[str, list[MeshData]] = {}

    # ------------------------------------------------------------------ assets

    def material(self, key: str, image: np.ndarray | None = None, rgb: RGB | None = None,
                 finish: tuple[float, float] = MATTE, tile_m: float = 1.0) -> None:
        """A material, textured from an in-memory RGB image (PNG bytes, no file) or of one colour."""
        kw: dict = {"specular": finish[0], "shininess": finish[1]}
        if image is not None:
            ok, png = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
            if not ok:
                raise ConfigError(f"could not encode the {key} texture of {self.prefix}")
            kw["texture"] = self.root.asset.add("texture", name=f"{self.prefix}_{key}", type="2d",
                                                file=mjcf.Asset(png.tobytes(), ".png"))
        if rgb is not None:
            kw["rgba"] = [*(np.asarray(rgb, float) / 255.0), 1.0]
        self.materials[key] = (self.root.asset.add("material", name=f"{self.prefix}_{key}", **kw), tile_m)
        self.parts[key] = []

    def tube(self, key: str, detail: str, tube: Tube, folds: tuple | None = None,
             cap_rings: int = CAP_RINGS) -> MeshData:
        """Mesh a tube into the material's part list; folds = (amplitude, around, along, envelope(n))."""
        n_around, n_along = DETAIL[detail]
        gains = fold_gains(self.rng, n_along, n_around, *folds[:3],  # type: ignore[misc]  # folds[:3]: three values
                           envelope=folds[3](n_along)) if folds else None
        mesh = tube_mesh(tube, self.materials[key][1], n_around, n_along, gains, cap_rings)
        self.parts[key].append(mesh)
        return mesh

    def blob(self, key: str, detail: str, centre, size) -> None:
        self.parts[key].append(ellipsoid_mesh(centre, size, self.materials[key][1], *DETAIL[detail]))

    def rod(self, key: str, points, radius: float) -> None:
        """A thin round-ended tube (neck, thumb, drawstring, zip) through the points."""
        r = (radius,) * len(points)
        self.tube(key, "rod", Tube(tuple(map(tuple, points)), r, r, start="round", end="round"), cap_rings=2)

    def sew(self) -> None:
        """One mesh asset and one geom per material."""
        for key, meshes in self.parts.items():
            if not meshes:
                continue
            mesh = merge_meshes(meshes)
            name = f"{self.prefix}_{key}"
            asset = self.root.asset.add("mesh", name=name, file=mjcf.Asset(_msh_bytes(mesh), ".msh"))
            self.body.add("geom", name=name, type="mesh", mesh=asset, material=self.materials[key][0],
                          contype=0, conaffinity=0, group=OCCLUDER_GROUP)

    # ------------------------------------------------------------------ the person

    def dress(self, o: Outfit) -> None:
        self.material("top", o.top_fabric.texture(), tile_m=o.top_fabric.tile_m)
        self.material("bottom", o.bottom_fabric.texture(), tile_m=o.bottom_fabric.tile_m)
        self.material("skin", skin_texture(o.skin, self._seed()), finish=SKIN_SHINE, tile_m=SKIN_TILE_M)
        self.material("hair", hair_texture(o.hair, self._seed()), finish=HAIR_SHINE, tile_m=HAIR_TILE_M)
        torso = self.torso(o)
        self.arms(o)
        self.lower(o)
        self.head(o)
        self.shoes(o)
        self.trim(o, torso)
        self.sew()

    def _seed(self) -> int:
        return int(self.rng.integers(2 ** 31))

    def torso(self, o: Outfit) -> MeshData:
        _, _, hem, ease, amplitude = TOPS[o.top]
        last = TORSO_PROFILE[-1]
        hem_row = (hem, last[1], last[2] + HEM_FLARE, last[3] + HEM_FLARE)
        rows = [r for r in TORSO_PROFILE if r[0] > hem + 0.02] + [hem_row]
        z, x, a, b = np.array(rows).T
        tube = Tube(tuple(zip(x, 0 * x, z)), tuple(a + ease), tuple(b * o.girth + ease),
                    TORSO_SQUARENESS, start="flat", end="flat")
        return self.tube("top", "torso", tube, (amplitude, *TORSO_DRAPE))

    def arms(self, o: Outfit) -> None:
        sleeve_kind, ease = TOPS[o.top][1], TOPS[o.top][3]
        for side in (1, -1):
            k = np.array(_mirror(ARM_KNOTS, side))
            if sleeve_kind == "short":
                arm = Tube(tuple(map(tuple, k)), ARM_RADII, tuple(ARM_FLATTEN * np.array(ARM_RADII)), end="round")
                self.tube("skin", "arm", arm)
                cut = k[1] + SHORT_SLEEVE * (k[2] - k[1])
                r = np.array(SHORT_SLEEVE_RADII) + ease
                sleeve = Tube((tuple(k[0]), tuple(k[1]), tuple(cut)), tuple(r), tuple(ARM_FLATTEN * r))
                self.tube("top", "short_sleeve", sleeve, SHORT_SLEEVE_FOLDS)
            else:
                r = np.array(SLEEVE_RADII) + ease
                sleeve = Tube(tuple(map(tuple, k)), tuple(r), tuple(ARM_FLATTEN * r))
                self.tube("top", "sleeve", sleeve, SLEEVE_FOLDS)
            self.hand(k[-1], side)

    def hand(self, wrist: np.ndarray, side: int) -> None:
        """A palm and a thumb that points forward, hanging below the wrist."""
        self.blob("skin", "hand", wrist + PALM[0], PALM[1])
        frm, to, radius = THUMB
        mirror = np.array([1.0, side, 1.0])
        self.rod("skin", (wrist + np.multiply(frm, mirror), wrist + np.multiply(to, mirror)), radius)

    def lower(self, o: Outfit) -> None:
        g = o.girth
        if o.bottom == "skirt":
            z, x, a, b = np.array(SKIRT + ((o.skirt_hem, -0.004, *SKIRT_HEM_SIZE),)).T
            skirt = Tube(tuple(zip(x, 0 * x, z)), tuple(a), tuple(b * g), TORSO_SQUARENESS, "flat", "flat")
            self.tube("bottom", "skirt", skirt, SKIRT_FOLDS)
            radii, leg_key, end, folds = BARE_LEG_RADII, "skin", "round", None
        else:
            z, x, a, b = np.array(PELVIS).T
            self.tube("bottom", "pelvis", Tube(tuple(zip(x, 0 * x, z)), tuple(a), tuple(b * g), TORSO_SQUARENESS,
                                               "flat", "round"))
            radii, leg_key, end = (JEANS_RADII if o.bottom == "jeans" else TROUSER_RADII), "bottom", "flat"
            folds = TROUSER_FOLDS
        r = tuple(np.array(radii) * g)
        for side in (1, -1):
            self.tube(leg_key, "leg", Tube(_mirror(LEG_KNOTS, side), r, r, start="round", end=end), folds)

    def head(self, o: Outfit) -> None:
        self.material("lips", rgb=tuple(int(LIP_SHADE * c) for c in o.skin),  # type: ignore[arg-type]  # 3 in, 3 out
                      finish=SKIN_SHINE)
        self.material("sclera", rgb=SCLERA_RGB, finish=POLISH)
        self.material("iris", rgb=IRIS_RGB, finish=POLISH)
        frm, to, r = NECK
        self.rod("skin", (frm, to), r)
        self.blob("skin", "head", HEAD_CENTRE, HEAD_SIZE)
        self.blob("skin", "feature", _on_head(*NOSE[0]), NOSE[1])
        self.blob("lips", "feature", _on_head(*LIPS[0]), LIPS[1])
        for side in (1, -1):
            (x, y, z), size = EAR
            self.blob("skin", "feature", (x, side * y, z), size)
            (y, z, depth), size = EYE
            eye = _on_head(side * y, z, depth)
            self.blob("sclera", "feature", eye, size)
            self.blob("iris", "feature", eye + [IRIS_FORWARD, 0, 0], (IRIS_RADIUS,) * 3)
            (y, z, depth), size = BROW
            self.blob("hair", "feature", _on_head(side * y, z, depth), size)
        self.hair(o.hair_style)

    def hair(self, style: str) -> None:
        """A crown cap (its front edge is the hairline) and a back piece down to the nape, plus extras."""
        thin = HAIR_BUZZ_SCALE if style == "buzz" else 1.0
        for pos, size in HAIR_PIECES:
            self.blob("hair", "hair", pos, np.array(size) * thin)
        if style == "long":
            self.blob("hair", "hair", *LONG_HAIR)
        elif style == "bun":
            self.blob("hair", "hair", *BUN)

    def shoes(self, o: Outfit) -> None:
        if o.shoes == "sneaker":
            canvas = Fabric("plain_weave", (o.shoe_colour,), self._seed())
            self.material("shoe", canvas.texture(), finish=MATTE, tile_m=canvas.tile_m)
        else:
            self.material("shoe", rgb=o.shoe_colour, finish=POLISH)
        self.material("sole", rgb=o.sole_colour, finish=MATTE)
        up = (0.0, 0.0, 1.0)  # shoes run along +X, so their cross-sections are measured from +Z
        (x0, x1), half_t, half_w = SOLE
        for side in (1, -1):
            y = side * LEG_KNOTS[-1][1]
            knots = tuple((x, y, z) for (x, z), _ in SHOE_UPPER)
            a, b = zip(*(size for _, size in SHOE_UPPER))
            self.tube("shoe", "shoe", Tube(knots, a, b, start="round", end="round", forward=up))
            sole = Tube(((x0, y, half_t), (x1, y, half_t)), (half_t,) * 2, (half_w,) * 2, 4.0, "round", "round", up)
            self.tube("sole", "shoe", sole, cap_rings=2)

    def trim(self, o: Outfit, torso: MeshData) -> None:
        """Collars, buttons, zips, hoods and pockets: what makes a garment read as that garment."""
        (x0, z0, a0, b0), (x1, z1, a1, b1) = COLLARS.get(o.top, CREW_NECK)
        self.tube("top", "collar", Tube(((x0, 0, z0), (x1, 0, z1)), (a0, a1), (b0, b1), start="flat", end="flat"))
        hem = TOPS[o.top][2]
        if o.top == "shirt":
            self.material("trim", rgb=_colour(self.rng, ("white", "cream", "black", "brown")), finish=POLISH)
            for z in np.arange(1.46, hem + 0.04, -BUTTON_PITCH):
                self.blob("trim", "feature", (_front_x(torso, z) + 0.001, 0, z), BUTTON_SIZE)
        elif o.top == "jacket":
            self.material("trim", rgb=ZIP_RGB, finish=POLISH)
            self.rod("trim", [(_front_x(torso, z) + 0.001, 0, z) for z in np.linspace(1.5, hem + 0.01, 8)], ZIP_RADIUS)
        elif o.top == "hoodie":
            self.blob("top", "hair", *HOOD)
            self.blob("top", "hair", (_front_x(torso, POCKET_Z) - POCKET_SIZE[0] + 0.008, 0, POCKET_Z), POCKET_SIZE)
            self.material("trim", rgb=_colour(self.rng, ("white", "cream", "black")), finish=MATTE)  # drawstrings
            for side in (1, -1):
                cord = [(_front_x(torso, z) + CORD_RADIUS - 0.001, side * CORD_Y, z) for z in np.linspace(*CORD_Z, 4)]
                self.rod("trim", cord, CORD_RADIUS)


def _msh_bytes(mesh: MeshData) -> bytes:
    """MuJoCo's binary MSH mesh format (counts, then float32 vertices, normals, texcoords, int32 faces):
    far quicker to hand over than MJCF text attributes."""
    counts = np.array([len(mesh.vertices), len(mesh.normals), len(mesh.texcoords), len(mesh.faces)], np.int32)
    arrays = (mesh.vertices, mesh.normals, mesh.texcoords)
    floats = [a.astype(np.float32).tobytes() for a in arrays]
    return b"".join([counts.tobytes(), *floats, mesh.faces.astype(np.int32).tobytes()])


def _on_head(y: float, z: float, depth: float) -> np.ndarray:
    """Point on the front of the head ellipsoid at (y, z), moved `depth` along +X (negative: sunk in)."""
    c, s = HEAD_CENTRE, HEAD_SIZE
    inside = 1.0 - ((y - c[1]) / s[1]) ** 2 - ((z - c[2]) / s[2]) ** 2
    return np.array([c[0] + s[0] * np.sqrt(max(inside, 0.0)) + depth, y, z])


def _front_x(mesh: MeshData, z: float) -> float:
    """x of a tube's front centre line at height z (where buttons and zips go)."""
    v = mesh.vertices
    front = v[(np.abs(v[:, 1]) < 0.012) & (v[:, 0] > 0)]
    order = np.argsort(front[:, 2])
    return float(np.interp(z, front[order, 2], front[order, 0]))
