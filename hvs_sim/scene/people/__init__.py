"""People who walk in front of the target: clothed, textured bodies, or the original plain figure.

A person 0.3–0.5 m from the lens fills most of the frame, so trackers see its clothes rather than
its outline: a flat-coloured slab is far easier to tell from the target than a person in a plaid
shirt. The textured style builds a body (rounded torso, shoulders, sleeves over arms, hands, neck,
head with face and hair, trousers or a skirt, shoes) from low-poly meshes whose texture
coordinates are metres of surface, so fabrics keep their real scale, with cloth folds in the
geometry. Fabrics are procedural and seeded (numpy/OpenCV): yarn-dyed weaves (tartan, gingham,
pinstripe, denim, chambray, twill, herringbone), knits (jersey, melange, stripes, chunky knit),
prints (dots, florals) and corduroy. Textures and meshes go to MuJoCo as in-memory assets.

Render cost (640×480 `Renderer.rgb()`, hand-held walk_by seed 0, frames 60–100, Mesa llvmpipe on a
shared 2-core machine, medians of 205 interleaved renders, three runs): plain 25.3–26.2 ms, textured
27.5–28.2 ms (+5–9 %; +8–11 % on the frames where the person fills the view).

The package is split along the module's former sections: `fabrics` (procedural cloth, skin and hair), `meshes`
(tubes, ellipsoids, folds), `outfits` (what a person wears) and `body` (body geometry, `Person`, the tailor and
the plain figure); the tiling noise and the weaves are in `hvs_sim/scene/noise.py`, shared with the wall
textures. Everything is re-exported here, so `hvs_sim.scene.people.X` works as before.
"""

from __future__ import annotations

from hvs_sim.scene.noise import HERRINGBONE_BAND  # noqa: F401
from hvs_sim.scene.people.body import (  # noqa: F401
    ARM_FLATTEN,
    ARM_KNOTS,
    ARM_RADII,
    BARE_LEG_RADII,
    BROW,
    BUN,
    BUTTON_PITCH,
    BUTTON_SIZE,
    COLLARS,
    CORD_RADIUS,
    CORD_Y,
    CORD_Z,
    CREW_NECK,
    DETAIL,
    EAR,
    EYE,
    HAIR_BUZZ_SCALE,
    HAIR_PIECES,
    HAIR_SHINE,
    HAIR_TILE_M,
    HEAD_CENTRE,
    HEAD_SIZE,
    HEM_FLARE,
    HOOD,
    IRIS_FORWARD,
    IRIS_RADIUS,
    IRIS_RGB,
    JEANS_RADII,
    LEG_KNOTS,
    LIP_SHADE,
    LIPS,
    LONG_HAIR,
    MATTE,
    NECK,
    NOSE,
    OCCLUDER_GROUP,
    PALM,
    PELVIS,
    PERSON_STYLES,
    POCKET_SIZE,
    POCKET_Z,
    POLISH,
    SCLERA_RGB,
    SHOE_UPPER,
    SHORT_SLEEVE,
    SHORT_SLEEVE_FOLDS,
    SHORT_SLEEVE_RADII,
    SKIN_SHINE,
    SKIN_TILE_M,
    SKIRT,
    SKIRT_FOLDS,
    SKIRT_HEM_SIZE,
    SLEEVE_FOLDS,
    SLEEVE_RADII,
    SOLE,
    THUMB,
    TORSO_DRAPE,
    TORSO_PROFILE,
    TORSO_SQUARENESS,
    TROUSER_FOLDS,
    TROUSER_RADII,
    ZIP_RADIUS,
    ZIP_RGB,
    Person,
)
from hvs_sim.scene.people.fabrics import (  # noqa: F401
    DYE_VARIATION,
    FABRIC_KINDS,
    GRAIN,
    THREAD_PX,
    YARN_SLUB,
    fabric_colours_needed,
    fabric_texture,
    hair_texture,
    knitted,
    periodic_noise,
    skin_texture,
    woven,
)
from hvs_sim.scene.people.meshes import (  # noqa: F401
    CAP_RINGS,
    FOLD_WAVES,
    ROUND_END_DEPTH,
    MeshData,
    Tube,
    ellipsoid_mesh,
    fold_gains,
    merge_meshes,
    tube_mesh,
)
from hvs_sim.scene.people.outfits import (  # noqa: F401
    BOTTOMS,
    CHINO,
    DARK,
    DRAW_TEXELS,
    ECRU,
    GARMENT_COLOURS,
    HAIR_COLOURS,
    HAIR_STYLES,
    INDIGO,
    LIGHT,
    MELANGE,
    RGB,
    SHOES,
    SKIN_TONES,
    TEXTURE_TEXELS,
    TILE_M,
    TOPS,
    Fabric,
    Outfit,
)
