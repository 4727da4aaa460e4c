"""The evidence a re-acquisition is checked on (tracking/evidence.py): the target's own surroundings tell it from a copy
of it, and overrule a chain that went wrong, not one that holds."""

from __future__ import annotations

import numpy as np
import pytest

from hvs_sim.errors import ConfigError
from hvs_sim.scene.textures import natural_texture
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.evidence import appearance, context_agreement
from hvs_sim.tracking.global_match import Match
from hvs_sim.tracking.warp import pose_to_matrix

ROI = (260, 190, 96, 80)  # x, y, w, h
COPY_AT = (480, 330)  # where a copy of the target is pasted (top-left), on other picture


def _scene() -> np.ndarray:
    return natural_texture("gravel", 640, 480, 5)


def _with_copy(img: np.ndarray, cover: bool) -> np.ndarray:
    """The scene with the target's picture pasted elsewhere (a shirt printed with it), the target itself covered by a
    flat grey coat when `cover`."""
    x, y, w, h = ROI
    out = img.copy()
    out[COPY_AT[1]:COPY_AT[1] + h, COPY_AT[0]:COPY_AT[0] + w] = img[y:y + h, x:x + w]
    if cover:
        out[y - 20:y + h + 20, x - 20:x + w + 20] = 128
    return out


def _shift(tr, dx: float, dy: float) -> np.ndarray:
    return pose_to_matrix((dx, dy, 0.0, 1.0), tr.center0)


def test_the_ring_around_the_target_tells_it_from_a_copy_that_looks_the_same():
    img = _scene()
    tr = make_tracker("hybrid")
    tr.init(img, ROI)
    al = tr.aligner
    frame = _with_copy(img, cover=False)
    work = al.work_image(frame)
    copy = al.to_work(_shift(tr, COPY_AT[0] - ROI[0], COPY_AT[1] - ROI[1]))
    target = al.to_work(np.eye(3))
    # the template itself shows equally at both: the global match's and the appearance's scores cannot tell them apart
    assert appearance(al, work, copy) > 0.99 and appearance(al, work, target) > 0.99
    assert context_agreement(al, work, target) > 0.99
    assert context_agreement(al, work, copy) < 0.5
    # a pose whose ring lies outside the frame gives no score rather than a made-up one
    assert context_agreement(al, work, al.to_work(_shift(tr, 900.0, 0.0))) is None


@pytest.mark.parametrize("context_check", [True, False])
def test_the_targets_surroundings_overrule_a_chain_that_went_wrong(context_check, monkeypatch):
    """A static target's estimate carried 100 px off by a chain the tracker trusts (measured on the surroundings since
    the alignment: the veto holds a far jump back); the target shows at its place, its match unique. Its ring of
    picture is where the template's view had it: taken at once. Without the check: held back."""
    img = _scene()
    tr = make_tracker("hybrid", target_motion="static", context_check=context_check)
    tr.init(img, ROI)
    monkeypatch.setattr(tr, "_surroundings_agree", lambda A, work: False)
    st = tr.state
    st.A, st.scene_held, st.drift_run = _shift(tr, 100.0, 0.0), True, 0
    unique = Match(np.zeros(2), 0.95, 0.4)
    work = tr.aligner.work_image(img)
    assert tr._verified(np.eye(3), unique, work) is context_check


def test_a_copy_of_the_covered_target_stays_held_back(monkeypatch):
    """The chain is right (the estimate on the covered target); a copy of the target elsewhere matches uniquely. Its
    ring is other picture: the veto holds, as it did before the check."""
    img = _scene()
    tr = make_tracker("hybrid", target_motion="static")
    tr.init(img, ROI)
    monkeypatch.setattr(tr, "_surroundings_agree", lambda A, work: False)
    st = tr.state
    st.scene_held, st.drift_run = True, 0
    work = tr.aligner.work_image(_with_copy(img, cover=True))
    copy = _shift(tr, COPY_AT[0] - ROI[0], COPY_AT[1] - ROI[1])
    unique = Match(np.zeros(2), 0.95, 0.4)
    assert not any(tr._verified(copy, unique, work) for _ in range(5))


def test_context_agree_is_checked():
    for bad in (1.5, "high", float("nan")):
        with pytest.raises(ConfigError, match="context_agree"):
            make_tracker("hybrid", context_agree=bad)
    with pytest.raises(ConfigError, match="context_check"):
        make_tracker("hybrid", context_check="yes")
    assert not make_tracker("hybrid_no_context").hconfig.context_check
