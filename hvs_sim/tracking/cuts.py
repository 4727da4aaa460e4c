"""Scene cuts for the hybrid tracker: a frame that shares nothing with the one before (footage edited from several
shots) is a cut, after which the target is `lost` until it is aligned again (HybridConfig.cut_ncc). Two frames are
compared on a small zero-mean thumbnail of the working image; kept apart from the motion sources, which measure where
a hidden target is, not whether the view is still the same shot."""

from __future__ import annotations

import cv2
import numpy as np

CUT_THUMB = (32, 24)  # the thumbnail two frames are compared on for a scene cut (w, h)
CUT_MIN_CONTRAST = 2.0 / 255  # a thumbnail with less RMS contrast (intensity in [0, 1]) has nothing to compare


def thumbnail(work: np.ndarray) -> np.ndarray | None:
    """A small zero-mean, unit-norm copy of the working image: two frames of one shot correlate on it, a cut does not.
    None for a frame without content to compare (a body or a hand filling the view, the lens covered): that is an
    occlusion, not a cut."""
    t = cv2.resize(np.asarray(work, np.float32), CUT_THUMB, interpolation=cv2.INTER_AREA).ravel()
    t = t - t.mean()
    norm = float(np.linalg.norm(t))
    return None if norm < CUT_MIN_CONTRAST * np.sqrt(t.size) else t / norm
