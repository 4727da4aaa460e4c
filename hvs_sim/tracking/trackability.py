"""Refuse a template no template tracker can localise (plain sky, a blank wall, a single edge).

Measured at `init` on the grey template at working resolution: the smallest eigenvalue of its mean
structure tensor (hvs_sim.texture_measure.trackability; zero for a flat patch, and for stripes in
one direction, which LK can slide along). Below `min_trackability` init raises an InputError; with
`allow_untrackable=True` it accepts the template and every Track carries a confidence scaled down
by the shortfall, so a caller can tell its positions are guesses.
"""

from __future__ import annotations

from hvs_sim.errors import InputError
from hvs_sim.texture_measure import trackability

# min eigenvalue of the mean structure tensor of the working-resolution template (intensity in
# [0, 1] per pixel, squared). Measured on 120×160 px crops through the phone_handheld camera: a
# plain sky 0.9e-6, a white wall 0.05e-6; the least textured natural textures (marble, wood grain,
# clouds) 3e-5, flags and photos 1e-4 to 3e-3. Set 5× above the noisy sky, so that no real target
# with some texture is refused
MIN_TRACKABILITY = 5e-6


def check_trackable(template_grey, min_trackability: float, allow_untrackable: bool, name: str) -> float:
    """The template's confidence factor in [0, 1]; raises InputError on an untrackable template
    unless `allow_untrackable`."""
    value = trackability(template_grey)
    if value >= min_trackability:
        return 1.0
    if not allow_untrackable:
        raise InputError(
            f"{name}: the template at this ROI has too little texture to be localised (trackability "
            f"{value:.2g} < {min_trackability:.2g}: smallest eigenvalue of its structure tensor; a flat or "
            "single-edge patch such as plain sky scores ~0). Choose an ROI on a textured part of the "
            "target, or pass allow_untrackable=True to track it anyway with a low confidence.")
    return max(0.0, value / min_trackability)
