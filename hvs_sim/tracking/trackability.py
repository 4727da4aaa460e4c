"""Refuse a template no template tracker can localise (plain sky, a blank wall, a single edge); accept a weakly
textured one with a note and a lowered confidence.

Measured at `init` on the grey template at working resolution, from its mean structure tensor with the sensor
noise's share taken out (hvs_sim.texture_measure.structure): noise raises both eigenvalues alike, so without that
a noisy plain sky or a noisy single edge would pass for texture, and a clean low-contrast lattice would not.
- flat: even the strongest direction holds less than FLAT_SIGNAL: refused;
- one direction: the weakest direction holds less than MIN_TRACKABILITY and under EDGE_RATIO of the strongest (a
  single straight edge, stripes, a ramp: LK can slide along it): refused;
- weak: any other template under MIN_TRACKABILITY is accepted; every Track's confidence is scaled down by the
  shortfall and the tracker's `notes` say so (`hvs-sim track` prints them).
`allow_untrackable=True` accepts the refused kinds too, with the same lowered confidence.
"""

from __future__ import annotations

from hvs_sim.errors import InputError
from hvs_sim.texture_measure import structure

# smallest eigenvalue (noise removed) of the mean structure tensor of the working-resolution template (intensity in
# [0, 1] per pixel, squared) above which a template is simply trackable. On 120×160 px crops with 2.5 grey levels of
# noise: clouds 2.3e-6 (weak), wood grain and posters 2–3e-5, photos 3e-5 to 2e-3; over it the hybrid keeps 97.7–100 % of
# frames within 2 px, under it 26–68 % (experiments/results/trackability)
MIN_TRACKABILITY = 5e-6
# a noisy plain patch leaves < 3e-8 in its strongest direction once the noise is taken out; a low-contrast lattice of
# 8 grey levels under 5 grey levels of noise 5e-7
FLAT_SIGNAL = 1e-7
# weakest over strongest direction of a single straight edge or ramp under noise: < 0.01; of 2-D natural textures
# 0.15–0.9, of the most oriented (wood grain) 0.03 with a weakest direction far above MIN_TRACKABILITY
EDGE_RATIO = 0.02


def check_trackable(template_grey, min_trackability: float, allow_untrackable: bool, name: str,
                    notes: list[str] | None = None) -> float:
    """The template's confidence factor in [0, 1] (module docstring); InputError on a flat or one-direction template
    unless `allow_untrackable`; a weak one adds a line to `notes`."""
    weakest, strongest = structure(template_grey)
    if weakest >= min_trackability:
        return 1.0
    confidence = max(0.0, weakest / min_trackability)
    kind = ("flat" if strongest < FLAT_SIGNAL else "one direction" if weakest < EDGE_RATIO * strongest else "weak")
    if kind != "weak" and not allow_untrackable:
        what = ("a flat patch (plain sky, a blank wall)" if kind == "flat" else
                "texture in one direction only (a single straight edge, stripes, a ramp), which a tracker can slide "
                "along")
        raise InputError(
            f"{name}: the template at this ROI is {what}: no tracker can localise it (structure tensor with the noise "
            f"taken out: weakest direction {weakest:.2g}, strongest {strongest:.2g}). Choose an ROI on a textured "
            "part of the target, or pass allow_untrackable=True to track it anyway with a low confidence.")
    if notes is not None:
        notes.append(f"weak template: its texture in the weakest direction is {weakest:.2g}, under the "
                     f"{min_trackability:.2g} of a well-textured one ({kind}); tracked with confidence "
                     f"{confidence:.2f}: expect drift and losses")
    return confidence
