"""GRU motion predictor of the paper's Fig. 5: two GRU layers (hidden 16) and FC 16 → 2.

Input: the last k confident translations as k − 1 consecutive displacements divided by `unit`
pixels (translation-invariant, O(1) values); output: the next displacement in the same unit.
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from hvs_sim.paths import WEIGHTS_DIR
from hvs_sim.tracking.nets.residual import load_module

GRU_PT = WEIGHTS_DIR / "gru.pt"
UNIT_PX = 4.0


class GRUPredictor(nn.Module):
    def __init__(self, hidden: int = 16, layers: int = 2):
        super().__init__()
        self.gru = nn.GRU(input_size=2, hidden_size=hidden, num_layers=layers, batch_first=True)
        self.fc = nn.Linear(hidden, 2)

    def forward(self, displacements: torch.Tensor) -> torch.Tensor:
        """(B, T, 2) normalised displacements → (B, 2) next displacement."""
        out, _ = self.gru(displacements)
        return self.fc(out[:, -1])


def load_gru(path: Path | str | None = None) -> GRUPredictor:
    net = GRUPredictor()
    net.meta = load_module(net, Path(path) if path else GRU_PT, "gru")
    return net.eval().requires_grad_(False)
