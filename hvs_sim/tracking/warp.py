"""2-D warps as 3×3 matrices (similarity or homography), and the tracker pose (tx, ty, θ, s) they stand for.

A pose is relative to the template at init: a template point x maps to c + t + s·R(θ)(x − c),
c being the template centre in the frame. For a homography the pose is its local similarity at
the template centre (where the centre goes, and the rotation and scale of the warp there).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from hvs_sim.errors import InputError, choice_error

WARPS = ("similarity", "homography")  # the warp models a tracker can estimate (`warp=` setting)
WARP_PARAMS = {"similarity": 4, "homography": 8}
TURN_ITERS = 6  # fit_turn's Gauss–Newton steps (it converges in 2–4 from a hop's similarity)
TURN_STEP = 1e-6  # its numerical derivative's step (rotation in rad; scale and shift in focal lengths)
TURN_DONE = 1e-9  # a step this small (same units) has converged


def check_warp(warp: str) -> str:
    """`warp` if it is one of WARPS, else a ConfigError listing them."""
    if warp not in WARPS:
        raise choice_error("warp", warp, WARPS)
    return warp


def similarity(tx: float, ty: float, theta: float, scale: float) -> np.ndarray:
    c, s = scale * math.cos(theta), scale * math.sin(theta)
    return np.array([[c, -s, tx], [s, c, ty], [0.0, 0.0, 1.0]])


def params_to_matrix(p: np.ndarray) -> np.ndarray:
    """LK parameterisation p = (a, b, tx, ty): [[1 + a, −b, tx], [b, 1 + a, ty]] (zero = identity)."""
    a, b, tx, ty = p
    return np.array([[1.0 + a, -b, tx], [b, 1.0 + a, ty], [0.0, 0.0, 1.0]])


def homography_params_to_matrix(p: np.ndarray) -> np.ndarray:
    """LK parameterisation of a homography, p = (p1 … p8): [[1 + p1, p2, p3], [p4, 1 + p5, p6], [p7, p8, 1]]."""
    return np.array([[1.0 + p[0], p[1], p[2]], [p[3], 1.0 + p[4], p[5]], [p[6], p[7], 1.0]])


def translate(A: np.ndarray, delta) -> np.ndarray:
    """A followed by an image translation by `delta` (moves the whole warped template, any warp model)."""
    T = np.eye(3)
    T[:2, 2] = delta
    return T @ A


def is_affine(A: np.ndarray) -> bool:
    return bool(A[2, 0] == 0.0 and A[2, 1] == 0.0 and A[2, 2] == 1.0)


def warp_image(image: np.ndarray, M: np.ndarray, size: tuple[int, int], **kwargs) -> np.ndarray:
    """cv2.warpAffine for an affine 3×3, cv2.warpPerspective otherwise (`kwargs`: flags, borderMode)."""
    if is_affine(M):
        return cv2.warpAffine(image, np.ascontiguousarray(M[:2]), size, **kwargs)
    return cv2.warpPerspective(image, M, size, **kwargs)


def pose_to_matrix(pose, center) -> np.ndarray:
    """Frame-from-template matrix of a pose about the template centre `center`."""
    tx, ty, theta, scale = pose
    cx, cy = center
    return np.array([[1, 0, cx + tx], [0, 1, cy + ty], [0, 0, 1.0]]) @ similarity(0, 0, theta, scale) @ \
        np.array([[1, 0, -cx], [0, 1, -cy], [0, 0, 1.0]])


def local_affine(A: np.ndarray, center) -> np.ndarray:
    """The affine map that agrees with the warp A to first order at `center` (A itself when affine)."""
    if is_affine(A):
        return A
    (a, b, c), (d, e, f), (g, h, i) = A.tolist()  # Python floats: a 3×3's numpy calls cost more than their sums
    cx, cy = float(center[0]), float(center[1])
    w = (g * cx + h * cy + i) or math.nan  # the centre on the horizon: no local affine, a non-finite answer
    mx, my = (a * cx + b * cy + c) / w, (d * cx + e * cy + f) / w  # where the centre goes
    j00, j01, j10, j11 = (a - mx * g) / w, (b - mx * h) / w, (d - my * g) / w, (e - my * h) / w  # the Jacobian there
    return np.array([[j00, j01, mx - (j00 * cx + j01 * cy)], [j10, j11, my - (j10 * cx + j11 * cy)], [0.0, 0.0, 1.0]])


def matrix_to_pose(A: np.ndarray, center) -> np.ndarray:
    """Inverse of `pose_to_matrix` (projects the warp's local affine part at the centre onto the nearest similarity)."""
    (a00, a01, a02), (a10, a11, a12), _ = local_affine(A, center).tolist()
    cx, cy = float(center[0]), float(center[1])
    a, b = 0.5 * (a00 + a11), 0.5 * (a10 - a01)
    return np.array([a00 * cx + a01 * cy + a02 - cx, a10 * cx + a11 * cy + a12 - cy, math.atan2(b, a), math.hypot(a, b)])


def project_similarity(A: np.ndarray, center) -> np.ndarray:
    """Nearest similarity to an affine 3×3 that maps `center` where the affine does."""
    a = 0.5 * (A[0, 0] + A[1, 1])
    b = 0.5 * (A[1, 0] - A[0, 1])
    c = np.asarray(center, float)
    S = np.array([[a, -b, 0.0], [b, a, 0.0], [0.0, 0.0, 1.0]])
    S[:2, 2] = A[:2, :2] @ c + A[:2, 2] - S[:2, :2] @ c
    return S


def apply(A: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Points (N, 2) through the warp A (affine or projective)."""
    pts = np.asarray(pts, float)
    out = pts @ A[:2, :2].T + A[:2, 2]
    if is_affine(A):
        return out
    w = pts @ A[2, :2] + A[2, 2]
    return out / w[:, None]


def in_view_share(box: np.ndarray, shape: tuple[int, int]) -> float:
    """The share of the convex quadrilateral `box` (4×2, px) that lies in a view `shape` (h, w) pixels: 1 all in view,
    0 none (1 for a degenerate box, which has no area to share out)."""
    h, w = shape
    pts = np.asarray(box, float)
    if np.all((pts >= -0.5) & (pts <= (w - 0.5, h - 0.5))):
        return 1.0
    quad = pts.astype(np.float32).reshape(-1, 1, 2)
    area = abs(float(cv2.contourArea(quad)))
    if not area > 0:
        return 1.0
    view = np.float32([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]]).reshape(-1, 1, 2)
    inside, _ = cv2.intersectConvexConvex(quad, view)
    return min(max(float(inside) / area, 0.0), 1.0)


def fit_similarity(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares similarity (3×3) taking points src → dst (Umeyama, no reflection)."""
    src, dst = np.asarray(src, float), np.asarray(dst, float)
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    denom = (a ** 2).sum()
    c = (a * b).sum() / denom  # s·cosθ
    s = (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum() / denom  # s·sinθ
    R = np.array([[c, -s], [s, c]])
    A = np.eye(3)
    A[:2, :2] = R
    A[:2, 2] = md - R @ ms
    return A


def fit_turn(S: np.ndarray, src: np.ndarray, dst: np.ndarray, focal: float, centre: np.ndarray) -> np.ndarray | None:
    """Least-squares "turn" src → dst (3×3): the homography K·R·K⁻¹ of a camera turning about its centre (focal
    length `focal`, principal point `centre`), then scaled and shifted; Gauss–Newton from the similarity S.

    A hand-held camera mostly turns: a wall then moves by this homography, whose perspective a similarity misses.
    Its 6 parameters extrapolate from a strip of the view where a free homography (8) does not. None where the fit
    is degenerate or not finite."""
    c = np.asarray(centre, float)
    p, q = (np.asarray(src, float) - c) / focal, (np.asarray(dst, float) - c) / focal
    x = np.zeros(6)  # rotation vector (3), log-scale, shift (2), in units of the focal length
    x[2], x[3] = math.atan2(S[1, 0], S[0, 0]), math.log(max(math.hypot(S[0, 0], S[1, 0]), 1e-12))
    x[4:] = (apply(S, c[None])[0] - c) / focal
    hom = np.c_[p, np.ones(len(p))]

    def residual(x: np.ndarray) -> np.ndarray:
        m = hom @ cv2.Rodrigues(x[:3])[0].T
        return (math.exp(x[3]) * m[:, :2] / m[:, 2:] + x[4:] - q).ravel()

    for i in range(TURN_ITERS):
        r = residual(x)
        J = np.stack([(residual(x + d) - r) / TURN_STEP for d in np.eye(6) * TURN_STEP], axis=1)
        # too few distinct points for six parameters: numpy's solve need not raise on the singular normal equations
        if i == 0 and np.linalg.matrix_rank(J) < 6:
            return None
        try:
            dx = np.linalg.solve(J.T @ J, -J.T @ r)
        except np.linalg.LinAlgError:
            return None
        x += dx
        if not np.all(np.isfinite(x)):
            return None
        if np.abs(dx).max() < TURN_DONE:
            break
    K = np.array([[focal, 0.0, c[0]], [0.0, focal, c[1]], [0.0, 0.0, 1.0]])
    s = math.exp(x[3])
    T = np.array([[s, 0.0, x[4]], [0.0, s, x[5]], [0.0, 0.0, 1.0]])
    H = K @ T @ cv2.Rodrigues(x[:3])[0] @ np.linalg.inv(K)
    return normalised_homography(H)


def normalised_homography(H: np.ndarray | None) -> np.ndarray | None:
    """An OpenCV homography scaled to H[2, 2] = 1, or None where there is none (not found, not finite, or
    H[2, 2] ≈ 0: a plane seen edge-on)."""
    if H is None or not np.all(np.isfinite(H)) or abs(H[2, 2]) < 1e-12:
        return None
    return H / H[2, 2]


def perspective_transform(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The homography (3×3, A[2, 2] = 1) taking four points src → dst, in float64 (cv2.getPerspectiveTransform
    works in float32: ~1e-4 px)."""
    src, dst = (np.asarray(p, np.float64) for p in (src, dst))
    if src.shape != (4, 2) or dst.shape != (4, 2) or not (np.all(np.isfinite(src)) and np.all(np.isfinite(dst))):
        raise InputError(f"a perspective transform takes 4 finite points (4×2) to 4, got {src.shape} and {dst.shape}")
    for pts in (src, dst):  # three on a line: no homography, or only a degenerate one
        for i in range(4):
            a, b, c = np.delete(pts, i, axis=0)
            if abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) < 1e-9 * max(np.ptp(pts), 1.0) ** 2:
                raise InputError("no homography takes these four points to the others: three of them lie on a line")
    H = normalised_homography(cv2.findHomography(src, dst, 0)[0])
    if H is None:
        raise InputError("no homography takes these four points to the others")
    return H


def inverse_3x3(M: np.ndarray) -> np.ndarray | None:
    """The inverse of a 3×3 matrix by its adjugate (a fifth of np.linalg.inv's call on so small a matrix, which the
    homography's Gauss–Newton loops make every step); None when it is singular."""
    (a, b, c), (d, e, f), (g, h, i) = M.tolist()
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * A + b * B + c * C
    if det == 0.0 or not math.isfinite(det):
        return None
    return np.array([[A, c * h - b * i, b * f - c * e], [B, a * i - c * g, c * d - a * f],
                     [C, b * g - a * h, a * e - b * d]]) / det
