"""What a patch of the frame says about a candidate pose of the target, beyond the global match's score: the checks of
a re-acquisition (hybrid.py).

- `appearance`: the template's NCC with the whole patch the pose aligns. Unlike OP_t it is blind to contrast, and
  unlike a masked measure it counts every pixel: a grey roof hatch and a grey facade differ by less than τ everywhere,
  and a half-faded copy of the target keeps most pixels within τ, yet the NCC of either with the template is low.
- `context_agreement`: the NCC of the ring of picture around the template, as the template's own view showed it, with
  the ring around the pose. A look-alike of the target (a shirt printed with the scene, a repeated motif, a spot along
  a kerb) rarely has the target's neighbours beside it as well; the target has them wherever the view went.
- `ring_steadiness`: the same ring between the last aligned frame and this one: whether anything moved against the
  alignment around the target (an occluder coming in, or the alignment pulled off the scene).

Both sample the frame through the pose with occlusion.aligned_patch (OpenCV's warpAffine/warpPerspective), in grey
work pixels, the template's geometry taken from the Aligner.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from hvs_sim.tracking.hybrid_config import APPEARANCE_MIN_SHOWN
from hvs_sim.tracking.occlusion import aligned_patch

if TYPE_CHECKING:
    from hvs_sim.tracking.aligner import Aligner

# the ring around the template, in template sides each way (the template's box itself left out): wide enough to reach
# past a person-sized look-alike printed with the scene, narrow enough that a similarity still fits a tilted view there
CONTEXT_PAD = 1.0
# Gaussian sigma (work px) on both rings: a similarity's misfit of a tilted hand-held view at the ring's edge, blur and
# noise move single pixels, not the ring's layout
CONTEXT_BLUR = 1.5
# share of the ring that must lie inside both the template's view and this frame for a score (else None)
CONTEXT_MIN_SHOWN = 0.2


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    den = float(np.sqrt((a @ a) * (b @ b)))
    return float(a @ b) / den if den > 1e-9 else -1.0


def appearance(al: Aligner, work: np.ndarray, A_work: np.ndarray) -> float:
    """The template's NCC with the whole patch A_work aligns (-1 when under APPEARANCE_MIN_SHOWN of it is in the
    frame)."""
    patch, inside = aligned_patch(work, A_work, al.t_origin, (al.th, al.tw))
    if inside.mean() < APPEARANCE_MIN_SHOWN:
        return -1.0
    return _ncc(patch.astype(np.float32)[inside], al.template.astype(np.float32)[inside])


def _rings_ncc(al: Aligner, then_work: np.ndarray, then_A: np.ndarray, work: np.ndarray, A_work: np.ndarray,
               pad: float) -> float | None:
    """NCC of the ring around the target (the box left out) that then_A puts in then_work with the one A_work puts in
    `work`, both blurred by CONTEXT_BLUR; None when under CONTEXT_MIN_SHOWN of the ring is in both."""
    px, py = round(pad * al.tw), round(pad * al.th)
    origin, shape = al.t_origin - np.array([px, py]), (al.th + 2 * py, al.tw + 2 * px)
    then, then_in = aligned_patch(then_work, then_A, origin, shape)
    now, now_in = aligned_patch(work, A_work, origin, shape)
    ring = then_in & now_in
    ring[py:py + al.th, px:px + al.tw] = False
    if ring.mean() < CONTEXT_MIN_SHOWN:
        return None
    blur = [cv2.GaussianBlur(p.astype(np.float32), (0, 0), CONTEXT_BLUR)[ring] for p in (then, now)]
    return _ncc(*blur)


def context_agreement(al: Aligner, work: np.ndarray, A_work: np.ndarray, pad: float = CONTEXT_PAD) -> float | None:
    """NCC of the ring around the template in the template's view (Aligner.init_work, where the identity holds) with
    the ring A_work puts around the target in `work`; None when under CONTEXT_MIN_SHOWN of the ring is in both."""
    return _rings_ncc(al, al.init_work, np.eye(3), work, A_work, pad)


def ring_steadiness(al: Aligner, then_work: np.ndarray, then_A: np.ndarray, work: np.ndarray, A_work: np.ndarray,
                    pad: float = CONTEXT_PAD) -> float:
    """The same between two frames: the ring the full-res pose then_A put around the target in then_work against the
    one A_work puts in `work`. Near 1 where the surroundings moved with the alignment and nothing came into them
    (HybridTracker._pulled); -1 when under CONTEXT_MIN_SHOWN of the ring is in both."""
    found = _rings_ncc(al, then_work, al.to_work(then_A), work, A_work, pad)
    return -1.0 if found is None else found
