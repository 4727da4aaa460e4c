"""The paper's hybrid tracker: global match → occlusion gate → deep LK + residual, or motion prediction.

Per frame: NCC over the whole frame gives a coarse centre and a score; OP_t is measured on the
patch at that centre and on the patch at the current estimate, and the better of the two is kept
(see DeepLKTracker.coarse). If OP_t < gate (40 %) and the match score ≥ 0.6 (or, with
`continuity`, the seed is the current estimate) the frame is aligned (feature LK, then
the residual regressor) and its translation joins the predictor's history; otherwise the predictor
(GRU by default) extrapolates the translation, holding θ and s. Re-acquisition is automatic: the
global match runs every frame, so the first frame that passes the gate is aligned again.

The predict path is bounded: after `max_predict_frames` consecutive predictions (default 45,
1.5 s at 30 Hz) the mode becomes "lost" and the estimate stops moving until re-acquisition.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hvs_sim.errors import ConfigError
from hvs_sim.tracking.base import Estimate
from hvs_sim.tracking.deep_lk import DeepLKConfig, DeepLKTracker
from hvs_sim.tracking.predictors import PREDICTORS, make_predictor
from hvs_sim.tracking.warp import matrix_to_pose, pose_to_matrix


@dataclass(frozen=True)
class HybridConfig:
    deep: DeepLKConfig = field(default_factory=lambda: DeepLKConfig(residual=True))
    occlusion_gate: float = 0.4
    predictor: str = "gru"
    history: int = 10
    max_predict_frames: int = 45
    gru_weights: str | None = None
    # True: a seed that continues the current track and passes the OP_t gate needs no NCC score
    # (partial occlusion drags the score below 0.6). Measured: more frames aligned under partial
    # occlusion but drift onto the occluder in others (README, tracking benchmark), so the paper's
    # rule (score ≥ 0.6 always) stays the default.
    continuity: bool = False

    def __post_init__(self):
        if not 0 < self.occlusion_gate <= 1:
            raise ConfigError(f"occlusion_gate must be in (0, 1], got {self.occlusion_gate}")
        if self.predictor not in PREDICTORS:
            raise ConfigError(f"unknown predictor {self.predictor!r}; accepted: {', '.join(PREDICTORS)}")
        if not isinstance(self.max_predict_frames, int) or self.max_predict_frames < 1:
            raise ConfigError(f"max_predict_frames must be an int >= 1, got {self.max_predict_frames!r}")


class HybridTracker(DeepLKTracker):
    name = "hybrid"

    def __init__(self, config: HybridConfig = HybridConfig()):
        super().__init__(config.deep)
        self.hconfig = config
        self.predictor = make_predictor(config.predictor, config.history, config.gru_weights)
        self.predict_run = 0

    def _init(self, frame, roi) -> None:
        super()._init(frame, roi)
        self.predictor.reset()
        self.predictor.observe(np.zeros(2))
        self.predict_run = 0

    def _update(self, frame) -> Estimate:
        work = self.work_image(frame)
        m, A_seed, occ, is_current = self.coarse(work)
        if m.score <= 0:  # blank or uniform frame
            occ = 1.0
        confident = m.score >= self.config.match_threshold or (self.hconfig.continuity and is_current)
        if occ < self.hconfig.occlusion_gate and confident:
            A_new, _ = self.align(work, A_seed)
            if A_new is not None:
                A = self.to_full(A_new)
                self.predictor.observe(matrix_to_pose(A, self.center0)[:2])
                self.predict_run = 0
                return Estimate(A, "align", occ, m.score)
        self.predict_run += 1
        if self.predict_run > self.hconfig.max_predict_frames:
            return Estimate(self.A, "lost", occ, m.score)
        pose = matrix_to_pose(self.A, self.center0)
        pose[:2] = self.predictor.predict()
        return Estimate(pose_to_matrix(pose, self.center0), "predict", occ, m.score)
