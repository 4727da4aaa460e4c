"""Natural-looking textures for the wall: procedural materials and crops of freely licensed photos.

Clean flags flatter every tracker; real walls carry wood, brick, posters, notice boards, plants and
fur-like surfaces whose texture repeats at every scale. `natural_texture(name, width, height, seed)`
returns an RGB uint8 image, a pure function of its arguments, so scenes and training sets built from
it are reproducible.

Procedural families use numpy + OpenCV only: fractal noise (sums of octaves of seeded value noise),
domain warping, jittered-grid Voronoi cells, line-integral convolution along a flow field, and
palettes read off photographs of the real materials. Feature sizes are given in pixels of a 512 px
image and scale with sqrt(width * height), so a texture keeps its look at other sizes.

Photo families crop the scikit-learn sample photos (china, flower) and the PyWavelets images
(aero, ascent). scikit-image's and matplotlib's sample photos are kept for a held-out evaluation and
must never be used here. There is no `photo_face`: PyWavelets (1.9) ships no face image (pywt.data
has aero, ascent, camera, ecg, nino), and `pywt.data.camera` is scikit-image's cameraman, excluded.

The package is split along the families' sections: `base` (the canvas and shared building blocks; the noise
octaves are in `hvs_sim/scene/noise.py`), `materials` (wood, marble, brick, gravel, foliage, fur, bark, sky,
granite, sand), `manmade` (poster, mosaic, woven fabric, cork board), `photos`, and `registry` (names, sets,
`natural_texture`, the contact sheet). Everything is re-exported here, so `hvs_sim.scene.textures.X` works as
before; patch a name in the module that looks it up (e.g. `textures.registry.natural_texture` for
`write_contact_sheet`).
"""

from __future__ import annotations

from hvs_sim.scene.textures.base import (  # noqa: F401
    LIGHT,
    MAX_SIDE,
    MIN_SIDE,
    REF_SIZE,
    Rgb,
)
from hvs_sim.scene.textures.manmade import (  # noqa: F401
    BODY_FONTS,
    CORK_GRANULE_PX,
    CORK_GRANULES,
    CORK_WEIGHTS,
    DENIM,
    FABRIC_HEATHER,
    GROUT_RGB,
    HANDWRITING_FONTS,
    MOSAIC_GROUND,
    MOSAIC_GROUT_PX,
    MOSAIC_OUTLINE,
    MOSAIC_STYLES,
    MOSAIC_TILE_PX,
    NOTE_PAPERS,
    NOTE_PX,
    NOTE_SHADOW_OFFSET_PX,
    NOTE_TILT_DEG,
    NOTES_PER_BOARD,
    PIN_COLOURS,
    POSTER_FONTS,
    POSTER_INKS,
    POSTER_JITTER,
    POSTER_LAYOUTS,
    POSTER_PAPERS,
    SKY_PALETTES,
    SYLLABLE_CODAS,
    SYLLABLE_ONSETS,
    SYLLABLE_VOWELS,
    TARTAN_COLOURS,
    TEXT_LINE_PX,
    THREAD_PX,
    TWEED,
)
from hvs_sim.scene.textures.materials import (  # noqa: F401
    BARK_COLOURS,
    BARK_CRACK_RGB,
    BARK_ELONGATION,
    BARK_FURROW_PX,
    BARK_RIDGE_PX,
    BRICK_PALETTES,
    BRICK_PX,
    CLOUD_BILLOW,
    CLOUD_BILLOW_PX,
    CLOUD_CELL_PX,
    CLOUD_COVER,
    CLOUD_EDGE,
    CLOUD_LIT,
    CLOUD_PUFF_PX,
    CLOUD_SHADOW,
    FOLIAGE_BACKGROUND,
    FOLIAGE_COVER,
    FOLIAGE_LAYER_DIM,
    FOLIAGE_LAYERS,
    FUR_COATS,
    FUR_GUARD_DENSITY,
    FUR_GUARD_PX,
    FUR_LIC_STEPS,
    FUR_LIC_SUBSTEP_PX,
    FUR_STRIPE_PX,
    FUR_UNDERCOAT_PX,
    GRANITE_CELL_PX,
    GRANITE_STONES,
    GRAVEL_CELL_PX,
    GRAVEL_GAP_RGB,
    GRAVEL_STONES,
    GRAVEL_WEIGHTS,
    LEAF_GREENS,
    LEAF_LENGTH_PX,
    LEAF_OUTLINE_POINTS,
    LEAF_WIDTH_RATIO,
    LICHEN_RGB,
    MARBLE_STONES,
    MARBLE_TURBULENCE,
    MARBLE_VEIN_PERIOD_PX,
    MARBLE_VEIN_WIDTH,
    MORTAR_PX,
    MORTAR_RGB,
    SAND_COLOURS,
    SAND_RIPPLE_CREST,
    SAND_RIPPLE_PX,
    SKY_HORIZON,
    SKY_ZENITH,
    WOOD_GAP_PX,
    WOOD_LATEWOOD_POWER,
    WOOD_PLANKS,
    WOOD_PORE_ASPECT,
    WOOD_RING_PX,
    WOOD_RING_STRETCH,
    WOOD_SPECIES,
)
from hvs_sim.scene.textures.photos import (  # noqa: F401
    GREY_TINT,
    PHOTO_CROP,
    PHOTO_SOURCES,
    _photo_source,
)
from hvs_sim.scene.textures.registry import (  # noqa: F401
    NATURAL_TEXTURES,
    PHOTO_TEXTURES,
    PROCEDURAL_TEXTURES,
    SHEET_COLUMNS,
    SHEET_LABEL_PX,
    TEXTURE_SETS,
    natural_texture,
    texture_set,
    write_contact_sheet,
)
from hvs_sim.texture_measure import trackability  # noqa: F401  (re-exported: texture sets are ranked by it)
