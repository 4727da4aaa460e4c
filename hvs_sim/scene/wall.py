"""What the flag wall shows: the target and the other 14 slots as flag names or RGB images, for one scenario.

Apart from world.py because it is a pure function of the scenario (images read, crops, seeded textures) that the
tests and the Scene call alike, with its own cache of generated textures.
"""

from __future__ import annotations

import functools

import numpy as np

from hvs_sim.errors import ConfigError
from hvs_sim.scene.flag_art import FLAG_NAMES
from hvs_sim.scene.images import TARGET_MAX_ASPECT, crop_to_aspect, list_images, load_image
from hvs_sim.scene.parts import FlagWall
from hvs_sim.scene.scenarios import MAX_TARGET_WIDTH, Scenario
from hvs_sim.scene.textures import TEXTURE_SETS, natural_texture

WALL_SEED_STRIDE = 1000  # texture seed of wall slot k: stride · scenario seed + k
SLOT_TEXELS = (450, 300)  # (width, height) of a natural-texture picture beside the target (3:2 like a flag)
TARGET_TEXELS = 600  # width of a natural-texture target


@functools.lru_cache(maxsize=256)
def _texture(name: str, width: int, height: int, seed: int) -> np.ndarray:
    img = natural_texture(name, width=width, height=height, seed=seed)
    img.setflags(write=False)
    return img


def wall_pictures(scenario: Scenario) -> tuple[str | np.ndarray, list | None]:
    """(target, the 14 other slots) for FlagWall: flag names or RGB images, a pure function of the scenario.

    The wall's textures change with the seed (a new set of posters per benchmark seed); a flag wall
    is the same for every seed, as before.
    """
    target: str | np.ndarray
    others: list[str | np.ndarray]
    if scenario.target_image:
        target = load_image(scenario.target_image, "target image", max_aspect=TARGET_MAX_ASPECT)
        height = scenario.target_width * target.shape[0] / target.shape[1]
        if height > MAX_TARGET_WIDTH:
            raise ConfigError(f"target image {scenario.target_image!r} would be {height:.2f} m tall at target_width "
                              f"{scenario.target_width} m; at most {MAX_TARGET_WIDTH} m: give a smaller target_width")
    elif scenario.target_texture:
        target = _texture(scenario.target_texture, TARGET_TEXELS, TARGET_TEXELS * 2 // 3, scenario.seed)
    else:
        target = scenario.target_flag
    n_others = FlagWall.ROWS * FlagWall.COLS - 1
    flags = [n for n in FLAG_NAMES if n != scenario.target_flag][:n_others]
    aspect = FlagWall.FLAG_H / FlagWall.FLAG_W
    if scenario.wall_images:
        files = list_images(scenario.wall_images)
        others = [crop_to_aspect(load_image(files[k % len(files)], "wall image"), aspect) for k in range(n_others)]
        return target, others
    if scenario.wall == "flags":
        return target, (None if isinstance(target, str) else flags)
    names = TEXTURE_SETS["natural" if scenario.wall == "mixed" else scenario.wall]
    others = []
    for k in range(n_others):
        if scenario.wall == "mixed" and k % 2 == 0:
            others.append(flags[k])
            continue
        name = names[(k + scenario.seed) % len(names)]
        others.append(_texture(name, *SLOT_TEXELS, WALL_SEED_STRIDE * scenario.seed + k))
    return target, others
