"""Deep LK, the paper's baseline: global NCC match → patch → frozen VGG-16 features → inverse-
compositional LK (→ the residual regressor for "Deep LK+Δ"), every frame, no occlusion handling.

The work is done by an `Aligner` (aligner.py), which the hybrid tracker composes too.
"""

from __future__ import annotations

import dataclasses

from hvs_sim.tracking.aligner import Aligner, DeepLKConfig, select_device
from hvs_sim.tracking.base import Estimate, Mode, Tracker
from hvs_sim.tracking.trackability import check_trackable

__all__ = ["DeepLKConfig", "DeepLKTracker", "select_device"]


class DeepLKTracker(Tracker):
    name = "deep_lk"

    def __init__(self, config: DeepLKConfig | None = None):
        super().__init__()
        self.config = config = config or DeepLKConfig()
        self.aligner = Aligner(config)
        self.warp = config.warp
        self._seeded = False  # the next frame aligns from the seed (Tracker.seed) too, not only global matches

    @property
    def working_scale(self) -> float:
        return self.config.scale

    def with_scale(self, scale: float) -> DeepLKTracker:
        tracker = type(self)(dataclasses.replace(self.config, scale=scale))
        tracker.name = self.name
        return tracker

    def _init(self, frame, roi) -> None:
        self._seeded = False
        self.aligner.set_template(frame, roi)
        self.template_confidence = check_trackable(self.aligner.template, self.config.min_trackability,
                                                   self.config.allow_untrackable, self.name, self.notes)

    def _seed(self, A) -> None:
        self._seeded = True

    def _update(self, frame) -> Estimate:
        al = self.aligner
        work = al.work_image(frame)
        m, A_work, _, _ = al.coarse(work, self.A, keep_current=self._seeded)
        self._seeded = False
        if m.score <= 0.0:
            return Estimate(self.A, Mode.LOST, 1.0, m.score)
        A_new = al.align(work, A_work).A_work
        if A_new is None:
            return Estimate(self.A, Mode.LOST, al.occlusion(work, A_work), m.score)
        return Estimate(al.to_full(A_new), Mode.ALIGN, al.occlusion(work, A_new), m.score)
