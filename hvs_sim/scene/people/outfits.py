"""What a person wears: garments, fabrics and colours, skin tone, hair and shoes, drawn from one generator
so that the same generator state always dresses the same person.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import cv2
import numpy as np

from hvs_sim.scene.people.fabrics import fabric_texture

# ------------------------------------------------------------------------------------------------
# Outfits: what a person wears, drawn from a private generator. Colours are sRGB 0..255.

RGB = tuple[int, int, int]
GARMENT_COLOURS: dict[str, RGB] = {
    "navy": (32, 42, 72), "black": (26, 26, 29), "charcoal": (62, 64, 68), "grey": (128, 130, 133),
    "white": (236, 236, 231), "cream": (228, 219, 196), "light_blue": (160, 188, 218), "sky": (112, 154, 205),
    "red": (168, 32, 42), "burgundy": (108, 28, 42), "olive": (98, 102, 58), "forest": (38, 78, 52),
    "khaki": (188, 168, 120), "tan": (168, 128, 84), "brown": (98, 68, 44), "mustard": (204, 158, 42),
    "orange": (214, 108, 42), "pink": (228, 160, 172), "rose": (196, 88, 110), "teal": (30, 116, 122),
    "purple": (88, 60, 118), "lavender": (172, 158, 206), "yellow": (232, 206, 88), "green": (78, 146, 82),
}
LIGHT = ("white", "cream", "light_blue", "pink", "lavender", "yellow")
DARK = ("navy", "black", "charcoal", "burgundy", "forest", "brown", "purple", "teal")
CHINO = ("khaki", "navy", "olive", "grey", "black", "tan", "charcoal", "cream", "brown")
INDIGO: tuple[RGB, ...] = ((26, 38, 72), (40, 58, 100), (74, 100, 142), (104, 132, 170), (36, 36, 40))
ECRU: RGB = (212, 204, 186)
MELANGE: tuple[RGB, ...] = ((150, 152, 155), (98, 100, 104), (196, 190, 178), (112, 124, 146), (60, 62, 66))
# skin tones from very light to deep, as sRGB under neutral light
SKIN_TONES: tuple[RGB, ...] = (
    (241, 212, 192), (230, 188, 162), (214, 166, 132), (196, 142, 106), (178, 132, 96),
    (158, 108, 74), (124, 82, 56), (96, 62, 42), (70, 46, 34),
)
HAIR_COLOURS: tuple[RGB, ...] = (
    (20, 18, 18), (44, 32, 24), (78, 54, 36), (120, 88, 58), (184, 152, 104), (116, 54, 30), (150, 148, 146),
)
TOPS = {  # kind: (fabrics, sleeve, hem height m, ease m added to the torso, fold amplitude)
    "tshirt": (("stripes", "jersey", "melange", "dots", "floral"), "short", 0.955, 0.004, 0.02),
    "shirt": (("gingham", "tartan", "pinstripe", "plain_weave", "chambray", "floral"), "long", 0.93, 0.006, 0.018),
    "jacket": (("denim", "tartan", "herringbone", "corduroy", "twill"), "long", 0.90, 0.010, 0.012),
    "hoodie": (("melange", "jersey"), "long", 0.93, 0.009, 0.02),
    "sweater": (("knit", "stripes"), "long", 0.95, 0.007, 0.015),
}
BOTTOMS = {
    "jeans": ("denim",),
    "trousers": ("twill", "herringbone", "corduroy", "tartan"),
    "skirt": ("tartan", "denim", "dots", "floral", "plain_weave", "gingham"),
}
HAIR_STYLES = ("short", "long", "bun", "buzz")
SHOES = ("sneaker", "leather")
# Fabrics are drawn at 0.3 mm per texel (4-texel yarns are 1.2 mm) and area-averaged to half that
# resolution for MuJoCo: 0.6 mm texels are about one pixel at 0.4 m, so a close person's textures are
# sampled magnified, which costs the software renderer less than minified (trilinear) sampling.
DRAW_TEXELS, TEXTURE_TEXELS = 512, 256
TILE_M = DRAW_TEXELS * 0.0003  # 0.154 m of cloth per texture tile


@dataclass(frozen=True)
class Fabric:
    """A cloth: its kind (FABRIC_KINDS), colours as `fabric_texture` reads them, and its texture's seed."""

    kind: str
    colours: tuple[RGB, ...]
    seed: int

    tile_m = TILE_M  # metres of cloth one texture tile covers

    def texture(self) -> np.ndarray:
        """TEXTURE_TEXELS² RGB uint8 tile, drawn at DRAW_TEXELS² and area-averaged (anti-aliased yarns)."""
        img = fabric_texture(self.kind, self.colours, self.seed, DRAW_TEXELS)
        return cv2.resize(img, (TEXTURE_TEXELS, TEXTURE_TEXELS), interpolation=cv2.INTER_AREA)


@dataclass(frozen=True)
class Outfit:
    """Everything that makes one person look different from another."""

    top: str
    top_fabric: Fabric
    bottom: str
    bottom_fabric: Fabric
    skin: RGB
    hair_style: str
    hair: RGB
    shoes: str
    shoe_colour: RGB
    sole_colour: RGB
    girth: float  # scales the width of the torso and the legs (not the depth: HALF_DEPTH stays true)
    skirt_hem: float  # height of a skirt's hem (m)

    @staticmethod
    def sample(rng: np.random.Generator) -> Outfit:
        """A random outfit; every draw comes from `rng`, so the same generator state gives the same person."""
        top = _pick(rng, tuple(TOPS))
        bottom = _pick(rng, tuple(BOTTOMS))
        top_kind = _pick(rng, TOPS[top][0])
        bottom_kind = _pick(rng, BOTTOMS[bottom])
        if bottom_kind == top_kind == "denim":  # no double denim: the jacket goes tartan
            top_kind = "tartan"
        shoes = _pick(rng, SHOES)
        sneaker = shoes == "sneaker"
        return Outfit(
            top=top, top_fabric=_fabric(rng, top_kind), bottom=bottom, bottom_fabric=_fabric(rng, bottom_kind),
            skin=_jitter(rng, _pick(rng, SKIN_TONES), 0.04),
            hair_style=_pick(rng, HAIR_STYLES), hair=_jitter(rng, _pick(rng, HAIR_COLOURS), 0.08),
            shoes=shoes,
            shoe_colour=_colour(rng, ("white", "black", "grey", "navy", "red") if sneaker else ("black", "brown")),
            sole_colour=_colour(rng, ("white", "cream") if sneaker else ("black", "brown")),
            girth=float(rng.uniform(0.95, 1.02)), skirt_hem=float(rng.uniform(0.5, 0.64)),
        )


def _pick(rng: np.random.Generator, options: tuple):
    return options[int(rng.integers(len(options)))]


def _jitter(rng: np.random.Generator, rgb: RGB, spread: float) -> RGB:
    return cast(RGB, tuple(int(np.clip(round(c * rng.uniform(1 - spread, 1 + spread)), 0, 255)) for c in rgb))


def _colour(rng: np.random.Generator, names: tuple[str, ...] = tuple(GARMENT_COLOURS), spread: float = 0.06) -> RGB:
    return _jitter(rng, GARMENT_COLOURS[_pick(rng, names)], spread)


def _distinct(rng: np.random.Generator, k: int, names: tuple[str, ...] = tuple(GARMENT_COLOURS)) -> tuple[RGB, ...]:
    chosen = rng.choice(len(names), size=k, replace=False)
    return tuple(_jitter(rng, GARMENT_COLOURS[names[i]], 0.05) for i in chosen)


def _fabric(rng: np.random.Generator, kind: str) -> Fabric:
    """A fabric of the given kind in colours that such cloth is usually made in."""
    colours: tuple[RGB, ...]
    if kind == "denim":
        colours = (_jitter(rng, _pick(rng, INDIGO), 0.06), _jitter(rng, ECRU, 0.04))
    elif kind == "chambray":
        colours = (_jitter(rng, INDIGO[3], 0.08), GARMENT_COLOURS["white"])
    elif kind == "melange":
        colours = (_jitter(rng, _pick(rng, MELANGE), 0.04),)
    elif kind in ("gingham", "pinstripe", "dots", "stripes"):
        light, dark = _colour(rng, LIGHT), _colour(rng, DARK + ("red", "sky", "green", "rose"))
        ground_first = kind in ("gingham", "pinstripe") or rng.uniform() < 0.6
        colours = (light, dark) if ground_first else (dark, light)
        if kind == "stripes" and rng.uniform() < 0.4:  # an accent stripe
            colours += (_colour(rng, ("red", "mustard", "sky", "green")),)
    elif kind == "tartan":
        colours = _distinct(rng, int(rng.integers(3, 5)),
                            ("red", "navy", "forest", "black", "yellow", "white", "burgundy", "sky", "green", "grey"))
    elif kind == "herringbone":
        pair = _pick(rng, (("charcoal", "grey"), ("brown", "khaki"), ("navy", "sky"), ("black", "white")))
        colours = tuple(_jitter(rng, GARMENT_COLOURS[c], 0.05) for c in pair)
    elif kind == "floral":
        ground = _colour(rng, LIGHT + ("navy", "black"))
        petals = _distinct(rng, 2, ("red", "rose", "sky", "lavender", "orange", "pink"))
        middle, leaf = _colour(rng, ("yellow", "white", "mustard")), _colour(rng, ("green", "forest", "olive"))
        colours = (ground, *petals, middle, leaf)
    elif kind in ("twill", "corduroy"):
        colours = (_colour(rng, CHINO + (("burgundy", "mustard") if kind == "corduroy" else ())),)
    else:  # knit, jersey, plain_weave
        colours = (_colour(rng),)
    return Fabric(kind, colours, int(rng.integers(2 ** 31)))
