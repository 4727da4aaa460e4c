"""`hvs-sim bench track --imagery natural`: trackers on real photographs filmed like a hand-held phone.

The hybrid is judged on held-out real-photo sequences (a portrait, a cat, a cup, a street… moved by
hand, with exposure drift, noise, JPEG and a person crossing or pausing over the target). Rendered
flag walls are not that, so this module builds sequences of the same kind from the ONLY image
sources this project may use: the scikit-learn sample photos (china, flower), the PyWavelets photos
(aero, ascent) and the procedural textures of `hvs_sim.scene.textures`; bodies are drawn from the
procedural fabrics of `hvs_sim.scene.people`. scikit-image's and matplotlib's sample photographs are
the held-out set's kind of data and must never be imported here; nor is `pywt.data.camera`, which is
scikit-image's cameraman (see scene/textures/__init__.py).

A sequence: a planar picture seen through a camera whose picture-to-image homography H_t drifts and
trembles like a phone in the hand (slow drift of a few px per frame, a few degrees of roll, ±3 %
scale, a little perspective, 1–10 Hz tremor). Frames are warped from the picture in LINEAR light at
2× and box-filtered to 1× (each pixel integrates its area: no aliasing), averaged over sub-frame
instants of the preset's exposure (motion blur), composited with a clothed body close to the lens
(blurred by its own motion), optionally lens-distorted, then captured by the preset's camera model
(`SensorState`: auto-exposure, noise, sRGB, JPEG) under its light changes (`light_scale`).

Ground truth: the ROI centre chosen at frame 0 is undistorted, taken onto the picture by H_0⁻¹ and
back into frame t by H_t (then distorted): exact, at the frame time, i.e. at the END of the exposure,
as the simulator's. Presets with lens distortion (webcam) are supported: the frames and the occluder
mask go through `distortion_maps`, the ground truth through `distort_points`.

Every draw is seeded by (source, seed) for the picture, camera path, ROI and sensor, so the kinds of
one (source, seed) are the same shot with and without the person (paired), and by the kind for the
person: the same (source, kind, seed, camera, n_frames, size) gives bit-identical frames.
"""

# The package's modules, one per part of the benchmark (the lower ones import nothing above them):
#   sources.py   the picture sources, occluder kinds, frame rate, seed streams and the seeded generator
#   picture.py   the picture in linear light and the hand-held camera path (HandHeldPath, _path, _warp)
#   person.py    the drawn person: Body, make_body, make_hand, PersonPath, _person
#   sequence.py  the ROI and the sequence: NaturalSequence, make_natural_sequence
#   bench.py     the benchmark: NaturalBenchConfig, run_natural_bench (workers run bench._natural_job), tables,
#                figures, smoke_config
# Code and tests import from this package; a monkeypatch of a name here reaches callers that look it up here
# (the CLI), not the package's own modules, which import from each other.

from hvs_sim.bench.natural.bench import (
    PREVIEW_SCALE,
    SHEET_SEQUENCES,
    TIMING_REFERENCE,
    VISIBLE_BELOW,
    NaturalBenchConfig,
    _natural_job,
    _sheet_keys,
    natural_figures,
    natural_table,
    run_natural_bench,
    smoke_config,
)
from hvs_sim.bench.natural.person import Body, PersonPath, make_body, make_hand
from hvs_sim.bench.natural.picture import MOTIONS, HandHeldPath, _path
from hvs_sim.bench.natural.sequence import NaturalSequence, make_natural_sequence
from hvs_sim.bench.natural.sources import (
    ALL_KINDS,
    DEFAULT_SEEDS,
    EXTRA_KINDS,
    FPS,
    NATURAL_KINDS,
    NATURAL_PHOTOS,
    NATURAL_PROCEDURAL,
    NATURAL_SOURCES,
    OCCLUDED_KINDS,
    _rng,
)

__all__ = [
    "ALL_KINDS",
    "DEFAULT_SEEDS",
    "EXTRA_KINDS",
    "FPS",
    "MOTIONS",
    "NATURAL_KINDS",
    "NATURAL_PHOTOS",
    "NATURAL_PROCEDURAL",
    "NATURAL_SOURCES",
    "OCCLUDED_KINDS",
    "PREVIEW_SCALE",
    "SHEET_SEQUENCES",
    "TIMING_REFERENCE",
    "VISIBLE_BELOW",
    "Body",
    "HandHeldPath",
    "NaturalBenchConfig",
    "NaturalSequence",
    "PersonPath",
    "_natural_job",
    "_path",
    "_rng",
    "_sheet_keys",
    "make_body",
    "make_hand",
    "make_natural_sequence",
    "natural_figures",
    "natural_table",
    "run_natural_bench",
    "smoke_config",
]
