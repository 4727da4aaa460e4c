"""The alignment engine shared by `deep_lk`, the hybrid and residual training: one template, its
working-resolution geometry, the global match that seeds it, feature LK, and the optional residual.

Everything runs on a grey working image at `scale` of the frame (the paper resizes frames for
speed; 0.5 keeps VGG at ~5 ms on two CPU cores). Warps passed in and out of `Aligner` methods are
frame-from-template matrices: `A` at full resolution, `A_work` at working resolution
(`to_work` / `to_full` convert); the LK itself works on `M = N A_work N⁻¹`, coordinates centred on
the template and divided by ρ (half its larger side).

The public API (used by the trackers and by `learn/data.py` alike):
`set_template`, `work_image`, `to_work`/`to_full`, `coarse`, `lk`, `align`, `occlusion`, `exposure_at`,
`shows_clearly`, `perspective`, `residual_inputs`, `refine`, `residual_improves`, and the template geometry (`rho`, `N`,
`c_work`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.aligner_config import DeepLKConfig, select_device
from hvs_sim.tracking.ecc import ecc_template
from hvs_sim.tracking.feature_lk import HUBER_K, MAD_TO_SIGMA, AlignResult, FeatureICLK
from hvs_sim.tracking.frames import roi_center, to_grey
from hvs_sim.tracking.global_match import GlobalMatcher, Match
from hvs_sim.tracking.intensity_ic import IntensityIC
from hvs_sim.tracking.nets.vgg import vgg16_pool2
from hvs_sim.tracking.occlusion import OcclusionReference, aligned_patch
from hvs_sim.tracking.warp import apply, fit_similarity, is_affine, matrix_to_pose, pose_to_matrix, translate

MIN_CROP = 16  # work px: a crop smaller than this on a side means the target is (nearly) off the frame
MIN_VALID = 0.3  # share of template points that must land inside the crop for an alignment to count
RECTIFY_DEG, RECTIFY_SCALE = 0.5, 0.01  # re-make the rectified search template past these θ, s changes
# the residual's correction is kept only when its feature cost is below this share of LK's own (a
# correction that does not improve the fit comes from a texture unlike the regressor's training)
RESIDUAL_GAIN = 1.0
# work px: the most the intensity refinement (ECC before intensity_ic.py) may move a template corner from LK's answer. On weakly textured templates (marble, wood
# grain: procedural textures) the 8-parameter feature LK ends 1–4 full-res px off and ECC brings it back, which a
# 1 work px cap refused (p90 of the worst corner 4.3 → 0.43 px); on the photos of the homography benchmark,
# not used to choose it, 1 → 2 moved median / p90 / max 0.111 / 1.22 / 3.87 → 0.076 / 0.72 / 1.37 px
INTENSITY_REFINE_MAX_PX = 2.0
IC_GAUSS = 5  # the Gaussian both images are smoothed by before the intensity refinement compares them (ECC's default)
GAIN_STRIDE = 2  # refine_intensity's exposure gain from every 2nd row and column (a quarter of the 0.4 ms)
# Aligner.coarse skips the search with the template as taken while the estimate is confirmed and OP_t there is at
# most this: on a partly hidden target that search's seed was what kept the alignment on it (bark, `partial`,
# natural benchmark: 84 frames ≤ 1 px without it against 125 with it)
AS_TAKEN_SKIP_OCCLUSION = 0.1
# work px kept around a patch's corners in Aligner.work_colour_near: bilinear sampling reads one pixel beyond
# a sample point, so the crop's edge is never read where the frame's would not be
COLOUR_CROP_MARGIN = 2
# a mask costs accuracy at the template's edges (0.05 → 0.16 px on a clear hand-held clip, with ECC), so the
# intensity refinement is masked only when part of the target is hidden
MASK_BELOW = 0.98


@dataclass
class LKOutput:
    """One plain feature-LK run: the result, and the crop's features it ran on."""

    result: AlignResult
    feats: dict[str, torch.Tensor]
    origin: np.ndarray  # work px of the crop's top-left pixel


@dataclass
class Alignment:
    """What `Aligner.align` found: the work warp (None: rejected), the LK run, whether Δ was kept."""

    A_work: np.ndarray | None
    lk: LKOutput | None
    residual_used: bool = False


class Aligner:
    """Template geometry at working resolution, VGG features, global match seeds, feature LK (+ Δ)."""

    def __init__(self, config: DeepLKConfig | None = None):
        config = DeepLKConfig() if config is None else config
        self.config = config
        self.device = select_device(config.device)
        self.net = vgg16_pool2(config.weights).to(self.device)
        self.matcher = GlobalMatcher()
        self.lk_engine = FeatureICLK(config.lk, config.warp)
        self.residual_net = None
        if config.residual:
            if "pool2" not in config.lk.levels:
                raise ConfigError("the residual regressor needs the pool2 LK level")
            from hvs_sim.tracking.nets.residual import load_residual

            self.residual_net = load_residual(config.residual_weights).to(self.device)
        s = config.scale
        self.S = np.array([[s, 0, 0.5 * s - 0.5], [0, s, 0.5 * s - 0.5], [0, 0, 1.0]])  # full → work pixels
        self.S_inv = np.linalg.inv(self.S)
        # wall ms of the stages of the current frame (VGG "features", feature "lk", ECC "refine");
        # trackers clear it per frame and report it (HybridTracker.stage_ms): two clock reads a stage
        self.stage_ms: dict[str, float] = {}
        self.shape: np.ndarray | None = None  # set_shape

    def _timed(self, stage: str, t0: float) -> None:
        self.stage_ms[stage] = self.stage_ms.get(stage, 0.0) + 1e3 * (time.perf_counter() - t0)

    # ----------------------------------------------------------------- images and frames

    def set_shape(self, C: np.ndarray | None) -> None:
        """The target's perspective beside the similarity (`shape`, work px, template frame): the LK aligns the family
        S·shape and returns S (HybridConfig.lk_perspective). From a correction C (full res, the template's frame) less
        its own similarity, which is the estimate's to carry: left in C, the two traded off and drifted against each
        other from frame to frame. None: the similarity alone."""
        if C is None:
            self.shape = None
            return
        C_work = self.to_work(C)
        self.shape = np.linalg.solve(fit_similarity(self.t_corners, apply(C_work, self.t_corners)), C_work)

    def work_image(self, frame: np.ndarray) -> np.ndarray:
        grey = to_grey(frame)
        self.full_grey = grey  # the frame at full resolution, for the intensity refinement
        if self.config.scale == 1.0:
            return grey
        return cv2.resize(grey, None, fx=self.config.scale, fy=self.config.scale, interpolation=cv2.INTER_AREA)

    def work_colour(self, frame: np.ndarray) -> np.ndarray:
        s = self.config.scale
        return frame if s == 1.0 else cv2.resize(frame, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)

    def work_colour_near(self, frame: np.ndarray, A_work: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The colour working image around the patch that A_work aligns, and the work-pixel position of its
        top-left corner: pixel for pixel what work_colour(frame) holds there, without resizing the whole
        frame. INTER_AREA at a scale of 1/k averages k×k blocks, so a crop that starts on a multiple of k
        and spans whole blocks gives the same pixels. A patch warped from it (the warp moved by the offset) is
        the same but where OpenCV's 1/32-px rounding of a sample point falls the other way: rare for an affine
        warp; for a homography, whose moved matrix rounds less alike, OP_t differed on 0 of 178 tilted hand-held
        frames' estimates, and the crop saves the whole frame's resize (~0.25 ms a frame)."""
        s = self.config.scale
        k = round(1.0 / s)
        corners = apply(A_work, self.t_corners)
        H, W = frame.shape[:2]
        behind = not is_affine(A_work) and bool(np.any(self.t_corners @ A_work[2, :2] + A_work[2, 2] <= 0))
        if s == 1.0 or abs(k * s - 1.0) > 1e-9 or H % k or W % k or behind or not np.all(np.isfinite(corners)):
            return self.work_colour(frame), np.zeros(2)
        m = COLOUR_CROP_MARGIN
        x0, y0 = (max(0, int(np.floor(corners[:, i].min())) - m) for i in (0, 1))
        x1 = min(W // k, int(np.ceil(corners[:, 0].max())) + m + 1)
        y1 = min(H // k, int(np.ceil(corners[:, 1].max())) + m + 1)
        if x1 - x0 < 2 or y1 - y0 < 2:
            return self.work_colour(frame), np.zeros(2)
        crop = frame[y0 * k:y1 * k, x0 * k:x1 * k]
        return cv2.resize(crop, None, fx=s, fy=s, interpolation=cv2.INTER_AREA), np.array([x0, y0], float)

    def features(self, work: np.ndarray, x0: int, y0: int, x1: int, y1: int, gain: float = 1.0
                 ) -> dict[str, torch.Tensor]:
        """VGG features of the crop [y0:y1, x0:x1] of `work`, its intensities divided by the exposure `gain`."""
        t0 = time.perf_counter()
        crop = np.ascontiguousarray(work[y0:y1, x0:x1], np.float32)
        if gain != 1.0:
            crop *= np.float32(1.0 / gain)
        with torch.inference_mode():
            out = self.net(torch.from_numpy(crop)[None, None].to(self.device), levels=self.config.lk.levels)
        feats = {k: v[0].float().cpu() for k, v in out.items()}
        self._timed("features", t0)
        return feats

    def crop_box(self, corners_work: np.ndarray, shape) -> tuple[int, int, int, int]:
        m = self.config.margin
        x0 = max(0, int(np.floor(corners_work[:, 0].min())) - m)
        y0 = max(0, int(np.floor(corners_work[:, 1].min())) - m)
        x1 = min(shape[1], int(np.ceil(corners_work[:, 0].max())) + m + 1)
        y1 = min(shape[0], int(np.ceil(corners_work[:, 1].max())) + m + 1)
        return x0, y0, x1, y1

    def to_work(self, A_full: np.ndarray) -> np.ndarray:
        return self.S @ A_full @ self.S_inv

    def to_full(self, A_work: np.ndarray) -> np.ndarray:
        return self.S_inv @ A_work @ self.S

    # ----------------------------------------------------------------- template

    def set_template(self, frame: np.ndarray, roi, intensity: bool = False) -> np.ndarray:
        """Take the template from `frame` at `roi`; returns the grey working image of that frame. `intensity`: also
        for a similarity, build the full-resolution intensity model that `perspective` refines on."""
        self.shape = None  # a new template's own view
        work = self.work_image(frame)
        x, y, w, h = roi
        self.template_full = self.full_grey[y:y + h, x:x + w].astype(np.float32)
        # its exposure gain (refine_intensity), from every GAIN_STRIDE-th pixel: one number needs no 7 000 ratios;
        # from the 8-bit pixels, whose log ratios come from OcclusionReference's table (the same values, a third of
        # the time)
        self.full_reference = OcclusionReference(
            np.ascontiguousarray(self.full_grey[y:y + h:GAIN_STRIDE, x:x + w:GAIN_STRIDE]))
        if intensity or (self.config.warp == "homography" and self.config.refine_intensity):  # its model of the template
            self.intensity_ic = IntensityIC(ecc_template(self.full_grey, roi, IC_GAUSS), IC_GAUSS, self.template_full,
                                            self.config.intensity_smooth)
        self.full_origin = np.array([x, y], float)
        s = self.config.scale
        self.center0 = roi_center(roi)
        self.c_work = apply(self.S, self.center0[None])[0]
        self.tw, self.th = max(8, round(w * s)), max(8, round(h * s))
        self.t_origin = self.c_work - np.array([(self.tw - 1) / 2.0, (self.th - 1) / 2.0])
        self.template, _ = aligned_patch(work, np.eye(3), self.t_origin, (self.th, self.tw))
        self.reference = OcclusionReference(self.template, self.config.tau_pix, self.config.normalise_exposure)
        self.init_work = work  # the template's view, to rectify the search template by the current θ, s
        self.search_template, self._rectified_for = self.template, (0.0, 1.0)
        self.rho = max(self.tw, self.th) / 2.0
        self.N = np.array([[1 / self.rho, 0, -self.c_work[0] / self.rho], [0, 1 / self.rho, -self.c_work[1] / self.rho],
                           [0, 0, 1]])
        self.N_inv = np.linalg.inv(self.N)
        # centres of the template's corner pixels (work px): what the crop around a warp must hold
        self.t_corners = self.t_origin + np.array([[0, 0], [self.tw - 1, 0], [self.tw - 1, self.th - 1],
                                                   [0, self.th - 1]])
        x0, y0, x1, y1 = self.crop_box(self.t_corners, work.shape)
        feats = self.features(work, x0, y0, x1, y1)
        lo, hi = self.t_origin - 0.5, self.t_origin + np.array([self.tw - 0.5, self.th - 0.5])
        self.lk_engine.set_template(feats, np.array([x0, y0], float), self.c_work, self.rho, (lo, hi))
        return work

    def template_patch(self, image: np.ndarray, A_work: np.ndarray | None = None) -> np.ndarray:
        """`image` (work resolution, grey or colour) warped into template coordinates (identity by default)."""
        return aligned_patch(image, np.eye(3) if A_work is None else A_work, self.t_origin, (self.th, self.tw))[0]

    def rectified_template(self, A: np.ndarray) -> np.ndarray:
        """The template as it should look at pose `A`: the init view rotated and scaled by A's θ, s.

        NCC is not invariant to rotation and scale; while servoing the target grows or shrinks by
        10 % and more, which would drag the score under the 0.6 gate. Re-made when θ or s moved
        by more than 0.5° or 1 %.
        """
        _, _, theta, scale = matrix_to_pose(A, self.center0)
        t0, s0 = self._rectified_for
        if abs(theta - t0) > np.radians(RECTIFY_DEG) or abs(scale / s0 - 1) > RECTIFY_SCALE:
            self.search_template, self._rectified_for = self.shaped_template(theta, scale), (theta, scale)
        return self.search_template

    def shaped_template(self, theta: float, scale: float) -> np.ndarray:
        """The init view turned by θ and scaled by s: a template pixel q (about the centre c) shows c + R(−θ)(q − c)/s."""
        return self.template_patch(self.init_work, pose_to_matrix((0.0, 0.0, -theta, 1.0 / scale), self.c_work))

    # ----------------------------------------------------------------- per frame

    def exposure_at(self, work: np.ndarray, A_work: np.ndarray) -> float:
        """The frame's exposure gain against the template's, on the patch A_work aligns (the mode of the
        per-pixel ratios, occlusion.py: an occluder's pixels and a seed a few pixels off spread their ratios
        away from it)."""
        patch, inside = aligned_patch(work, A_work, self.t_origin, (self.th, self.tw))
        return self.reference.trusted_gain(patch, inside)

    def shows_clearly(self, work: np.ndarray, A_work: np.ndarray, B_work: np.ndarray, visible: float,
                      evidence: float, discernible: bool = False) -> bool:
        """Whether the frame shows the template clearly better at A_work than at B_work. Fit: the mean absolute grey
        residual, after each pose's exposure gain, over the share `visible` of the template's pixels that fit best
        (least trimmed residuals): an occluder's pixels fit badly at both poses and are trimmed, so the visible
        target's pixels decide, its edges included (OP_t's τ = 30 is blind to a low-contrast target's misalignment).
        Clearly: by at least the share `evidence` of what the template tells the two poses apart by, the same trimmed
        mean of its differences from itself moved from one pose to the other; closer fits do not say which is right (a
        coat's edge on a smooth photo pulled an alignment 4 px and fitted 0.3 grey levels better, where the template
        differs from itself 4 px away by 1.3: photos' dev split, `long` ascent). `discernible`: also not where that
        difference is under the better fit's own residual (a featureless target fits as well wherever it is moved; the
        fits then differ only by what covers them). Both poses carry the target's perspective (`shape`)."""
        shape = np.eye(3) if self.shape is None else self.shape
        t32 = self.reference.t32
        residuals = []
        for A in (A_work, B_work):
            patch, inside = aligned_patch(work, A @ shape, self.t_origin, (self.th, self.tw))
            g = np.float32(self.reference.trusted_gain(patch, inside))
            residuals.append(np.abs(patch.astype(np.float32) - g * t32)[inside])
        # the share is of the pixels both poses keep inside the frame: one pose's pixels off the frame are not a misfit
        k = round(float(np.clip(visible, 0.0, 1.0)) * min(r.size for r in residuals))
        if k < 1:
            return False
        fit_a, fit_b = (float(np.mean(np.partition(r, k - 1)[:k])) for r in residuals)
        if evidence == 0.0 and not discernible:
            return fit_b >= fit_a
        # the template moved from A to B, in its own frame: what a misfit of that size looks like
        moved, inside = aligned_patch(t32, translate(np.linalg.solve(A_work @ shape, B_work @ shape), -self.t_origin),
                                      self.t_origin, (self.th, self.tw))
        d = np.abs(moved - t32)[inside]
        apart = float(np.mean(np.partition(d, min(k, d.size) - 1)[:k])) if d.size else 0.0
        if discernible and apart < min(fit_a, fit_b):
            return False
        return fit_b - fit_a >= evidence * apart

    def occlusion(self, work: np.ndarray, A_work: np.ndarray) -> float:
        patch, inside = aligned_patch(work, A_work, self.t_origin, (self.th, self.tw))
        return self.reference(patch, inside)

    def coarse(self, work: np.ndarray, A: np.ndarray, keep_current: bool = True
               ) -> tuple[Match, np.ndarray, float, bool]:
        """Global match, and the work-resolution warp to start from (θ, s kept from the pose `A`).

        Two candidates: the current estimate, and the current estimate moved to the global match's
        centre. OP_t is measured on the patch each of them aligns, and the one showing the target
        best (lowest OP_t) wins: under partial occlusion the NCC peak can jump to another place
        while the current estimate still sits on the visible part of the target.
        The search uses the template rectified by the current θ, s and, unless that search confirms an
        unhidden estimate (`always_search_as_taken`, AS_TAKEN_SKIP_OCCLUSION), the template as taken; a
        match of the latter seeds θ = 0, s = 1. With `search_near_first` the rectified template is first
        searched only near the estimate; when that confirms it, no global search runs and the estimate is
        the seed, as it would be after them unless a look-alike elsewhere showed the target less hidden
        than the ≤ AS_TAKEN_SKIP_OCCLUSION it shows here. With keep_current=False (the paper's Deep LK
        baseline) only global-match seeds are considered.
        Returns (match, seed warp, OP_t at the seed, whether the seed is the current estimate).
        """
        A_prev = self.to_work(A)
        rectified = self.rectified_template(A)
        search = self.matcher.prepare(work)  # shared by all searches
        c_prev = apply(A_prev, self.c_work[None])[0]
        # OP_t at the current estimate: a candidate whenever it is kept, so measured once here
        op_prev = self.occlusion(work, A_prev) if keep_current else None
        if keep_current and self.config.search_near_first and op_prev <= AS_TAKEN_SKIP_OCCLUSION:
            near = self.matcher.match_near(search, rectified, c_prev)
            if self._confirms(near, c_prev):
                return near, A_prev, op_prev, True
        matches = [(self.matcher.match(search, rectified), A_prev)]
        first = matches[0][0]
        # the rectified template found the target where the estimate is, confidently, and the target
        # shows there unhidden: the search with the template as taken (its seed, θ = 0 and s = 1, wins
        # when θ, s went wrong under partial occlusion) is skipped unless the config asks for it
        confirmed = keep_current and self._confirms(first, c_prev) and op_prev <= AS_TAKEN_SKIP_OCCLUSION
        if rectified is not self.template and (self.config.always_search_as_taken or not confirmed):
            matches.append((self.matcher.match(search, self.template), np.eye(3)))
        m = max(matches, key=lambda mk: mk[0].score)[0]
        seeds = []
        for match, A_shape in matches:
            if not np.all(np.isfinite(match.center)):
                continue
            if A_shape is A_prev and np.linalg.norm(match.center - c_prev) <= self.config.reinit_px:
                seeds.append((match, A_prev))  # agrees with the current estimate: keep its sub-pixel pose
                continue
            seeds.append((match, translate(A_shape, match.center - apply(A_shape, self.c_work[None])[0])))
        if keep_current:
            candidates = [A_prev] + [sd for _, sd in seeds if sd is not A_prev]
        else:
            candidates = [sd for match, sd in seeds if match is m] or [A_prev]
        best = None
        for cand in candidates:
            op = op_prev if cand is A_prev and op_prev is not None else self.occlusion(work, cand)
            if best is None or op < best[1]:
                best = (cand, op)
        seed, op = best
        return m, seed, op, seed is A_prev

    def _confirms(self, m: Match | None, c_prev: np.ndarray) -> bool:
        """Whether a match finds the target confidently where the estimate (centre c_prev) has it."""
        return (m is not None and m.score >= self.config.match_threshold and bool(np.all(np.isfinite(m.center)))
                and np.linalg.norm(m.center - c_prev) <= self.config.reinit_px)

    def lk(self, work: np.ndarray, A_work: np.ndarray) -> LKOutput | None:
        """Plain feature LK from A_work on a crop around it, or None when the crop is too small (target off the frame).
        With `normalise_lk_exposure` the crop is first divided by the exposure gain at A_work (`exposure_at`)."""
        W = A_work if self.shape is None else A_work @ self.shape
        x0, y0, x1, y1 = self.crop_box(apply(W, self.t_corners), work.shape)
        if x1 - x0 < MIN_CROP or y1 - y0 < MIN_CROP:
            return None
        gain = self.exposure_at(work, A_work) if self.config.normalise_lk_exposure else 1.0
        feats = self.features(work, x0, y0, x1, y1, gain)
        origin = np.array([x0, y0], float)
        t0 = time.perf_counter()
        res = self.lk_engine.align(feats, origin, (y1 - y0, x1 - x0), self.N @ W @ self.N_inv)
        self._timed("lk", t0)
        return LKOutput(res, feats, origin)

    def residual_inputs(self, feats, origin, M) -> tuple[torch.Tensor, torch.Tensor]:
        """(256, rows, cols) template ⊕ aligned pool2 features and the warp [tx/ρ, ty/ρ, θ, s − 1].

        Both feature maps are divided by the template's mean activation, so the regressor sees the
        same scale whatever the target's contrast.
        """
        template = self.lk_engine.template_grid("pool2")
        scale = template.mean().clamp_min(1e-6)
        stacked = torch.cat([template, self.lk_engine.aligned_grid(feats, origin, M, "pool2")], 0) / scale
        pose = matrix_to_pose(M, (0.0, 0.0))  # normalised coordinates: centre at 0, unit ρ
        warp = torch.tensor([pose[0], pose[1], pose[2], pose[3] - 1.0], dtype=torch.float32)
        return stacked, warp

    def refine(self, feats, origin, M) -> np.ndarray:
        """Apply the regressor's Δp (ρ-scaled units, see nets/residual.py) to the LK warp M."""
        stacked, warp = self.residual_inputs(feats, origin, M)
        with torch.inference_mode():
            d = self.residual_net(stacked[None].to(self.device), warp[None].to(self.device))[0].cpu().double().numpy()
        pose = matrix_to_pose(M, (0.0, 0.0))
        pose = pose + np.array([d[0], d[1], d[2], d[3]]) / self.rho
        return pose_to_matrix(pose, (0.0, 0.0))

    def residual_improves(self, out: LKOutput, M_ref: np.ndarray) -> bool:
        """Whether the residual's warp M_ref fits the template's features better than LK's own
        answer: robust (Huber) feature cost on the finest LK level, over the points both see,
        with one scale taken from LK's residuals so that the two costs compare."""
        r0, in0 = self.lk_engine.residuals(out.feats, out.origin, out.result.M)
        r1, in1 = self.lk_engine.residuals(out.feats, out.origin, M_ref)
        both = in0 & in1
        if both.sum() < MIN_VALID * len(both):
            return False
        k = HUBER_K * max(MAD_TO_SIGMA * np.median(r0[both]), 1e-6)

        def huber(r):
            return float(np.mean(np.where(r <= k, 0.5 * r ** 2, k * (r - 0.5 * k))))

        return huber(r1[both]) < RESIDUAL_GAIN * huber(r0[both])

    def align(self, work: np.ndarray, A_work: np.ndarray, estimate: np.ndarray | None = None, frames: int = 1,
              aligned: tuple[np.ndarray, int] | None = None) -> Alignment:
        """Feature LK (+ residual) from A_work; `A_work` of the result is None when the alignment is rejected (a jump
        of θ or s, too few points in view, a scale or shift no camera makes). θ and s may continue the seed's, or
        `estimate`'s (the current estimate, work px; a seed from the template as taken, θ = 0 and s = 1, would
        refuse a target seen rolled), or `aligned`'s (the last alignment, work px, and the frames since). `frames`:
        how many frames ago `estimate`'s θ and s were measured; the target may turn and scale by a step in each (dev
        `pause` seed 279: 8° from an estimate the predictor had moved for 5 frames, refused on every later frame)."""
        out = self.lk(work, A_work)
        if out is None:
            return Alignment(None, None)
        res = out.result
        used = False
        if self.residual_net is not None and np.all(np.isfinite(res.M)):
            M_ref = self.refine(out.feats, out.origin, res.M)
            # verified: the correction must fit the template's features better than LK's own answer
            used = not self.config.verify_residual or self.residual_improves(out, M_ref)
            if used:
                res.M = M_ref
        A_new = self.N_inv @ res.M @ self.N
        if self.shape is not None and np.all(np.isfinite(A_new)):  # the similarity S of the family S·shape
            pts = np.vstack([self.t_corners, self.c_work[None]])
            A_new = fit_similarity(pts, apply(A_new @ np.linalg.inv(self.shape), pts))
        if self.config.warp == "homography" and self.config.refine_intensity and np.all(np.isfinite(A_new)):
            t0 = time.perf_counter()
            A_ecc = self.refine_intensity(A_new)
            self._timed("refine", t0)
            # kept only near LK's answer: ECC has no robust weights, an occluder can pull it away
            if A_ecc is not None and np.abs(apply(A_ecc, self.t_corners) - apply(A_new, self.t_corners)).max() <= \
                    INTENSITY_REFINE_MAX_PX:
                A_new = A_ecc
        if not np.all(np.isfinite(A_new)) or not self.plausible_shape(A_new):
            return Alignment(None, out, used)
        scale = matrix_to_pose(A_new, self.c_work)[3]
        moved = np.linalg.norm(apply(A_new, self.c_work[None]) - apply(A_work, self.c_work[None]))
        jump = (self._jumps(A_work, A_new) and (estimate is None or self._jumps(estimate, A_new, frames))
                and (aligned is None or self._jumps(aligned[0], A_new, aligned[1])))
        if not 0.5 < scale < 2.0 or moved > self.rho or res.valid < MIN_VALID or jump:
            return Alignment(None, out, used)
        return Alignment(A_new, out, used)

    def _jumps(self, A_from: np.ndarray, A_new: np.ndarray, frames: int = 1) -> bool:
        """Whether A_new's rotation or scale differs from A_from's by more than `frames` frames' steps allow."""
        _, _, d_theta, d_scale = matrix_to_pose(np.linalg.solve(A_from, A_new), self.c_work)
        c = self.config
        return abs(d_theta) > c.max_rotation_step * frames or abs(d_scale - 1) > c.max_scale_step * frames

    def refine_intensity(self, A_work: np.ndarray) -> np.ndarray | None:
        """The homography from A_work refined on the full-resolution grey template, with the exposure's gain
        and offset fitted (intensity_ic.py); the refined work warp, or None when that fails. VGG features
        change with perspective (they are not equivariant to it), which biased LK's corners by 0.1–0.3 px."""
        T = np.array([[1, 0, self.full_origin[0]], [0, 1, self.full_origin[1]], [0, 0, 1.0]])
        A_full = self.to_full(A_work)
        # template pixels that the frame shows as they were (not an occluder), as in OP_t; measured at full
        # resolution on every call: a thin occluder that the working image's 2×2 averaging hides from OP_t shows here
        patch, inside = aligned_patch(self.full_grey, A_full, self.full_origin, self.template_full.shape)
        gain = self.full_reference.gain(patch[::GAIN_STRIDE, ::GAIN_STRIDE], inside[::GAIN_STRIDE, ::GAIN_STRIDE]) \
            if self.config.normalise_exposure else 1.0
        seen = inside & (np.abs(patch.astype(np.float32) - gain * self.template_full) < self.config.tau_pix)
        shown = seen.mean()
        if shown < MIN_VALID:
            return None
        result = self.intensity_ic.align(self.full_grey, A_full @ T, seen if shown < MASK_BELOW else None)
        if result is None:
            return None
        A = result.warp @ np.linalg.inv(T)
        w = float(A[2, :2] @ self.center0 + A[2, 2])  # scale so that w = 1 (> 0) at the template, not at the frame origin
        return self.to_work(A / w) if abs(w) > 1e-12 else None

    def perspective(self, A_work: np.ndarray) -> np.ndarray | None:
        """The homography of the target's plane near a similarity alignment A_work, measured on the full-resolution
        grey template (refine_intensity), or None where it is not found, folds, or moves A_work's centre by more than
        INTENSITY_REFINE_MAX_PX (an occluder pulled it). The corners are not compared: they are where a similarity
        and a tilted plane differ most (3.6 work px on that sequence, with the centres 1.3 apart). A similarity is the
        best fit of the paper's warp, not the target's place: under a tilted view it missed the centre by up to 3.9 px
        while aligned on every frame (photos' dev split, clear china of seed 7). Needs set_template(...,
        intensity=True)."""
        t0 = time.perf_counter()
        A_h = self.refine_intensity(A_work)
        self._timed("refine", t0)
        if A_h is None or not np.all(np.isfinite(A_h)) or not self.plausible_shape(A_h):
            return None
        apart = np.linalg.norm(apply(A_h, self.c_work[None]) - apply(A_work, self.c_work[None]))
        return A_h if apart <= INTENSITY_REFINE_MAX_PX else None

    def plausible_shape(self, A_work: np.ndarray) -> bool:
        """Whether the template's corners under A_work form a convex quadrilateral in front of the
        camera (always true for a similarity; a homography pulled by an occluder can fold)."""
        if is_affine(A_work):
            return True
        if np.any(self.t_corners @ A_work[2, :2] + A_work[2, 2] <= 0):  # a corner behind the camera
            return False
        quad = apply(A_work, self.t_corners)
        edges = np.roll(quad, -1, axis=0) - quad
        cross = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
        return bool(np.all(cross > 0) or np.all(cross < 0))
