"""The model a hop of the surroundings' chain carries (background.BackgroundMotion): its similarity consensus, the
homography refitted on the consensus where it spreads over the view, the plane grown from it among all the followed
points, or the camera's turn, chosen by Torr's GRIC where a model with more parameters competes with the similarity.
A picture on a wall moves as a plane, but the visible part of the wall can be a narrow strip beside an occluder, from
which a free homography extrapolates badly to the hidden target (background's module docstring)."""

from __future__ import annotations

from typing import Protocol

import cv2
import numpy as np

from hvs_sim.tracking.warp import apply, fit_turn, normalised_homography


class HopSettings(Protocol):
    """What hop_model reads of background.BackgroundConfig (named here so that this module needs nothing of it)."""

    @property
    def ransac_px(self) -> float: ...

    @property
    def grow_plane(self) -> bool: ...

    @property
    def turn(self) -> bool: ...


RANSAC_MAX_ITERS = 500  # enough for 30 % inliers among 200 corners (RANSAC here, in background.py and anchor.py)
# a hop refitted as a homography (BackgroundConfig.homography): on at least this many inliers, spread over at least
# this share of the view's width and height, and moving the view's centre within HOMOGRAPHY_AGREE_PX of the similarity
HOMOGRAPHY_MIN_INLIERS = 20
HOMOGRAPHY_SPREAD = 0.6
HOMOGRAPHY_AGREE_PX = 1.0
# the plane grown from a hop's similarity consensus (BackgroundConfig.grow_plane): RANSAC homographies over all followed
# points, up to PLANE_MODELS of them (each among the points the ones before did not take: a coat's own consensus can be
# the largest), the first that holds PLANE_KEEP of the similarity's inliers being the plane that contains them
PLANE_MODELS = 3
PLANE_KEEP = 0.8
# ... spread over this share of the view both ways (GRIC judges the rest): beside a coat over half the view, strips of
# 0.2-0.35 of it, whose similarity or turn missed the hidden target by 0.3-1.5 work px a hop (docs/results.md)
GROWN_PLANE_SPREAD = 0.3
# GRIC (Torr, "Geometric motion segmentation and model selection", 1998) for a 2-D point transfer: residuals in units of
# the noise σ (half the RANSAC threshold), each capped at λ3·(r − d) = 2·(4 − 2) = 4 (an outlier's cost); a model pays
# log(r·n) per parameter (similarity 4, camera turn 6, homography 8). The λ1·d·n term is the same for both and cancels
GRIC_CAP = 4.0
GRIC_R = 4
SIMILARITY_DOF, TURN_DOF, HOMOGRAPHY_DOF = 4, 6, 8
# the nominal focal length of the camera's turn (BackgroundConfig.turn), in widths of the view: a phone's or webcam's
# ~50-60° field. The fit barely depends on it (dev split, the coat's hops: 0.6 and 1.6 widths within 0.02 work px)
TURN_FOCAL = 1.0


def carries_plane(pts: np.ndarray, shape: tuple[int, int], spread: float = HOMOGRAPHY_SPREAD) -> bool:
    """Whether a hop's points can carry a homography: HOMOGRAPHY_MIN_INLIERS of them, spread over `spread` of the
    view both ways (a strip of wall extrapolates one badly)."""
    h, w = shape
    return len(pts) >= HOMOGRAPHY_MIN_INLIERS and bool(np.ptp(pts[:, 0]) >= spread * w) and \
        bool(np.ptp(pts[:, 1]) >= spread * h)


def plane_refit(S: np.ndarray, src: np.ndarray, dst: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The hop's similarity consensus (`src` → `dst`, its inliers) refitted as a homography where the points can
    carry one (HOMOGRAPHY_*), else S."""
    if not carries_plane(src, shape):
        return S
    H = normalised_homography(cv2.findHomography(src, dst, 0)[0])
    if H is None:
        return S
    centre = view_centre(shape)[None]
    return H if np.linalg.norm(apply(H, centre) - apply(S, centre)) <= HOMOGRAPHY_AGREE_PX else S


def view_centre(shape: tuple[int, int]) -> np.ndarray:
    """The centre (x, y) of a view `shape` (h, w) pixels."""
    h, w = shape
    return np.array([(w - 1) / 2.0, (h - 1) / 2.0])


def gric(M: np.ndarray, src: np.ndarray, dst: np.ndarray, sigma: float, dof: int) -> float:
    """GRIC of the 2-D transfer M over the correspondences src → dst (lower is better; GRIC_* above)."""
    e2 = np.sum((apply(M, src) - dst) ** 2, axis=1) / sigma ** 2
    return float(np.minimum(e2, GRIC_CAP).sum() + dof * np.log(GRIC_R * len(src)))


def gric_prefers(M: np.ndarray, dof: int, S: np.ndarray, src: np.ndarray, dst: np.ndarray, ransac_px: float) -> bool:
    """Whether GRIC prefers M (`dof` parameters) to the similarity S over src → dst, σ half the RANSAC threshold
    (False where either is not finite)."""
    sigma = ransac_px / 2
    return bool(gric(M, src, dst, sigma, dof) < gric(S, src, dst, sigma, SIMILARITY_DOF))


def grown_plane(S: np.ndarray, inl: np.ndarray, src: np.ndarray, dst: np.ndarray, shape: tuple[int, int],
                 ransac_px: float, occluder: np.ndarray | None = None) -> np.ndarray | None:
    """The homography of the plane that contains the similarity consensus (S, its inliers `inl`) among the followed
    points src → dst but the `occluder`'s, where its inliers spread over the view (GROWN_PLANE_SPREAD) and GRIC
    prefers it to S; else None (PLANE_*, GRIC_*). A coat beside a strip of wall moved 1 px apart from it over a hop,
    and a homography bent across both fits them (a shear), placing the hidden target by the coat's motion."""
    left = np.ones(len(src), bool) if occluder is None else ~occluder
    for _ in range(PLANE_MODELS):
        idx = np.flatnonzero(left)
        if len(idx) < HOMOGRAPHY_MIN_INLIERS:
            return None
        found, mask = cv2.findHomography(src[idx], dst[idx], cv2.RANSAC, ransac_px, maxIters=RANSAC_MAX_ITERS)
        H = normalised_homography(found)
        if H is None:
            return None
        plane = np.zeros(len(src), bool)
        plane[idx[mask[:, 0].astype(bool)]] = True
        if (plane & inl).sum() >= PLANE_KEEP * inl.sum():
            break
        left &= ~plane
    else:
        return None
    if not carries_plane(src[plane], shape, GROWN_PLANE_SPREAD):
        return None
    return H if gric_prefers(H, HOMOGRAPHY_DOF, S, src, dst, ransac_px) else None


def hop_model(S: np.ndarray, inl: np.ndarray, src: np.ndarray, dst: np.ndarray, shape: tuple[int, int],
               c: HopSettings, occluder: np.ndarray | None = None) -> np.ndarray:
    """The motion a hop chains, from its similarity consensus (S, its inliers `inl` among src → dst): the plane that
    contains it (grow_plane), else its inliers' homography where they carry one, else their camera turn where GRIC
    prefers it on them (turn), else S."""
    grown = grown_plane(S, inl, src, dst, shape, c.ransac_px, occluder) if c.grow_plane else None
    if grown is not None:
        return grown
    p, q = src[inl], dst[inl]
    refit = plane_refit(S, p, q, shape)
    if refit is not S or not c.turn:
        return refit
    turned = fit_turn(S, p, q, TURN_FOCAL * shape[1], view_centre(shape))
    if turned is None or not gric_prefers(turned, TURN_DOF, S, p, q, c.ransac_px):
        return S  # a strip that moves as a similarity: the turn's two more parameters would only fit its noise
    return turned
