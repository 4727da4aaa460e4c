"""Residual regressor of the paper's Fig. 4 and its weight loading.

Input: template and LK-aligned patch features concatenated (2C = 256 channels on the pool2 grid),
plus the current warp [tx, ty, θ, s]. Output: the correction Δp added to the LK estimate.
Units (so the four outputs weigh alike): tx, ty and Δtx, Δty in working pixels divided by ρ
(half the template's larger side), θ in radians, s − 1; the loss is taken on ρ-scaled values.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch
from torch import nn

from hvs_sim.errors import WeightsError
from hvs_sim.paths import WEIGHTS_DIR

RESIDUAL_PT = WEIGHTS_DIR / "residual.pt"


class ResidualRegressor(nn.Module):
    def __init__(self, in_channels: int = 256):
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, 64, 3, padding=1)
        self.conv2 = nn.Conv2d(64, 32, 3, padding=1)
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.fc1 = nn.Linear(36, 32)
        self.fc2 = nn.Linear(32, 4)

    def forward(self, feats: torch.Tensor, warp: torch.Tensor) -> torch.Tensor:
        """feats: (B, 256, Hf, Wf); warp: (B, 4) → Δp (B, 4)."""
        x = torch.relu(self.conv1(feats))
        x = torch.relu(self.conv2(x))
        x = self.pool(x).flatten(1)
        x = torch.relu(self.fc1(torch.cat([x, warp], dim=1)))
        return self.fc2(x)


def load_module(module: nn.Module, path: Path, what: str) -> dict:
    """Load a state dict into `module`, checking that the file exists and every shape matches."""
    from hvs_sim.validate import check_regular_file

    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise WeightsError(f"{what} weights not found at {path}; train them with `hvs-sim train {what}`")
    check_regular_file(path, f"{what} weights", WeightsError)  # a FIFO would block the read forever
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)  # weights_only: no pickled code runs
    except Exception as exc:  # noqa: BLE001 - torch raises many kinds for a corrupt file; all mean the same here
        first = str(exc).splitlines()[0] if str(exc) else ""
        raise WeightsError(f"{path} is not a readable torch weights file ({type(exc).__name__}: {first}); only "
                           "tensors are loaded, pickled objects are refused") from None
    if not isinstance(state, dict) or not all(hasattr(v, "shape") for v in state.values()):
        raise WeightsError(f"{path} does not hold a state dict of tensors; it does not hold {what} weights")
    expected = module.state_dict()
    missing = sorted(set(expected) - set(state))
    if missing:
        raise WeightsError(f"{path} lacks {missing}; it does not hold {what} weights")
    for k, v in expected.items():
        if tuple(state[k].shape) != tuple(v.shape):
            raise WeightsError(f"{path}: {k} has shape {tuple(state[k].shape)}, the {what} network needs {tuple(v.shape)}")
    module.load_state_dict({k: state[k] for k in expected})
    meta_path = path.with_suffix(".json")
    return json.loads(meta_path.read_text()) if meta_path.exists() else {}


def load_residual(path: Path | str | None = None) -> ResidualRegressor:
    net = ResidualRegressor()
    net.meta = load_module(net, Path(path) if path else RESIDUAL_PT, "residual")
    return net.eval().requires_grad_(False)
