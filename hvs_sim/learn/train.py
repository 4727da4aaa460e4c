"""`hvs-sim train residual` and `hvs-sim train gru`: seeded training on simulator data.

Each writes <name>.pt plus <name>.json (training configuration, data sizes, validation figures)
into the output folder (assets/weights by default: the package ships what these commands make).
"""

from __future__ import annotations

import json
import random
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from hvs_sim.errors import ConfigError
from hvs_sim.outputs import write_atomic, write_with
from hvs_sim.paths import WEIGHTS_DIR

# what the residual regressor's training frames are, written beside its weights (see learn/data.py, augment.py)
RESIDUAL_DATA_NOTE = ("targets: the 15 flags interleaved with the procedural textures (learn.data.TRAINING_TARGETS); "
                      "no photographs (scikit-image's and matplotlib's are reserved for independent evaluation); "
                      "70 % of samples through shot + read noise and JPEG (learn.augment.SENSOR_SHARE)")


def _seed_all(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


@dataclass(frozen=True)
class ResidualTrainConfig:
    sequences: int = 96
    frames_per_sequence: int = 24
    epochs: int = 60
    lr: float = 1e-3
    weight_decay: float = 1e-4
    val_share: float = 0.2
    seed: int = 0

    def __post_init__(self):
        if self.sequences < 2 or self.frames_per_sequence < 2 or self.epochs < 1:
            raise ConfigError("need sequences >= 2, frames_per_sequence >= 2 and epochs >= 1")


@dataclass(frozen=True)
class GRUTrainConfig:
    handheld_tracks: int = 120
    arm_tracks: int = 120
    track_length: int = 180
    history: int = 10
    horizon: int = 20  # frames unrolled in training (the predictor feeds itself while the target is hidden)
    noise_px: float = 0.05
    epochs: int = 30
    batch: int = 256
    lr: float = 3e-3
    val_share: float = 0.2
    seed: int = 0

    def __post_init__(self):
        if self.handheld_tracks + self.arm_tracks < 2 or self.track_length <= self.history + 1:
            raise ConfigError("need at least 2 tracks longer than history + 1 frames")
        if self.history < 3:
            raise ConfigError("history must be >= 3")


def _split(n: int, share: float, seed: int) -> tuple[list[int], list[int]]:
    idx = np.random.default_rng(seed).permutation(n)
    n_val = max(1, round(share * n))
    return sorted(idx[n_val:].tolist()), sorted(idx[:n_val].tolist())


def train_residual(config: ResidualTrainConfig = ResidualTrainConfig(), out_dir: Path = WEIGHTS_DIR,
                   progress: bool = True) -> dict:
    from tqdm.auto import tqdm

    from hvs_sim.learn.data import residual_dataset
    from hvs_sim.tracking.nets.residual import ResidualRegressor

    _seed_all(config.seed)
    torch.set_num_threads(2)
    t0 = time.time()
    data = residual_dataset(config.sequences, config.frames_per_sequence, progress=progress)
    groups = data["groups"]
    if len(groups) < 2:
        raise ConfigError("too few usable training sequences were generated; raise --sequences")
    train_idx, val_idx = _split(len(groups), config.val_share, config.seed)
    net = ResidualRegressor()
    opt = torch.optim.AdamW(net.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, config.epochs)
    loss_fn = nn.SmoothL1Loss(beta=0.5)

    def evaluate(idx):
        net.eval()
        per_kind: dict[str, list] = {}
        with torch.no_grad():
            tot = base = n = 0.0
            for i in idx:
                g = groups[i]
                pred = net(g["feats"].float(), g["warp"])
                tot += float(((pred - g["label"]) ** 2).sum())
                base += float((g["label"] ** 2).sum())
                n += g["label"].numel()
                after = torch.linalg.vector_norm(pred[:, :2] - g["label"][:, :2], dim=1)
                before = torch.linalg.vector_norm(g["label"][:, :2], dim=1)
                for k, a, b in zip(g["kind"], after.tolist(), before.tolist()):
                    per_kind.setdefault(k, []).append((b, a))
        net.train()
        kinds = {k: {"samples": len(v), "lk_translation_error_px_work": float(np.mean([b for b, _ in v])),
                     "residual_translation_error_px_work": float(np.mean([a for _, a in v]))} for k, v in per_kind.items()}
        return tot / n, base / n, kinds

    history = []
    rng = np.random.default_rng(config.seed)
    for epoch in tqdm(range(config.epochs), disable=not progress, desc="train residual", unit="epoch"):
        for i in rng.permutation(train_idx):
            g = groups[i]
            opt.zero_grad()
            loss = loss_fn(net(g["feats"].float(), g["warp"]), g["label"])
            loss.backward()
            opt.step()
        sched.step()
        if epoch % 5 == 4 or epoch == config.epochs - 1:
            history.append({"epoch": epoch + 1, "val_mse": evaluate(val_idx)[0]})
    val_mse, val_base, kinds = evaluate(val_idx)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_with(out_dir / "residual.pt", lambda tmp: torch.save(net.state_dict(), tmp))
    meta = {"network": "ResidualRegressor (paper Fig. 4)", "config": asdict(config),
            "train_sequences": len(train_idx), "val_sequences": len(val_idx),
            "train_samples": int(sum(len(groups[i]["kind"]) for i in train_idx)),
            "val_samples": int(sum(len(groups[i]["kind"]) for i in val_idx)),
            "val_mse": val_mse, "val_mse_without_residual": val_base, "val_by_degradation": kinds,
            "history": history, "seconds": round(time.time() - t0, 1), "seeds": "simulator seeds 1000+ (benchmarks use 100-999)",
            "data": RESIDUAL_DATA_NOTE}
    write_atomic(out_dir / "residual.json", json.dumps(meta, indent=2))
    return meta


def rollout(net, x: torch.Tensor, horizon: int) -> torch.Tensor:
    """Feed the predictor its own output for `horizon` frames: (B, T, 2) → (B, horizon, 2) displacements."""
    outs = []
    for _ in range(horizon):
        d = net(x)
        outs.append(d)
        x = torch.cat([x[:, 1:], d[:, None]], 1)
    return torch.stack(outs, 1)


def position_errors(pred_disp: torch.Tensor, true_disp: torch.Tensor) -> torch.Tensor:
    """(B, H) distance between predicted and true positions after each step (cumulative displacements)."""
    return torch.linalg.vector_norm(pred_disp.cumsum(1) - true_disp.cumsum(1), dim=-1)


def train_gru(config: GRUTrainConfig = GRUTrainConfig(), out_dir: Path = WEIGHTS_DIR, progress: bool = True) -> dict:
    from tqdm.auto import tqdm

    from hvs_sim.learn.data import gru_tracks, gru_windows
    from hvs_sim.tracking.nets.gru import UNIT_PX, GRUPredictor

    _seed_all(config.seed)
    torch.set_num_threads(2)
    t0 = time.time()
    tracks = gru_tracks(config.handheld_tracks, config.arm_tracks, config.track_length, progress=progress)
    train_idx, val_idx = _split(len(tracks), config.val_share, config.seed)
    rng = np.random.default_rng(config.seed)
    Xt, Yt = gru_windows([tracks[i] for i in train_idx], config.history, UNIT_PX, config.noise_px, rng, config.horizon)
    Xv, Yv = gru_windows([tracks[i] for i in val_idx], config.history, UNIT_PX, config.noise_px, rng, config.horizon)
    net = GRUPredictor()
    opt = torch.optim.Adam(net.parameters(), lr=config.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, config.epochs)
    history = []
    for epoch in tqdm(range(config.epochs), disable=not progress, desc="train gru", unit="epoch"):
        perm = torch.from_numpy(rng.permutation(len(Xt)))
        for b in range(0, len(Xt), config.batch):
            idx = perm[b:b + config.batch]
            opt.zero_grad()
            loss = ((rollout(net, Xt[idx], config.horizon) - Yt[idx]) ** 2).sum(-1).mean()
            loss.backward()
            opt.step()
        sched.step()
        if epoch % 5 == 4 or epoch == config.epochs - 1:
            with torch.no_grad():
                err = position_errors(rollout(net, Xv, config.horizon), Yv)
                history.append({"epoch": epoch + 1, "val_mean_position_error_px": float(err.mean()) * UNIT_PX})
    with torch.no_grad():
        gru_err = position_errors(rollout(net, Xv, config.horizon), Yv) * UNIT_PX
        cv = Xv[:, -5:].mean(1, keepdim=True).expand(-1, config.horizon, -1)  # last 5 displacements, continued
        cv_err = position_errors(cv, Yv) * UNIT_PX
        hold_err = position_errors(torch.zeros_like(Yv), Yv) * UNIT_PX

    def at(err):
        return {f"{h}_frames": float(err[:, h - 1].mean()) for h in sorted({1, 5, 10, config.horizon}) if h <= config.horizon}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_with(out_dir / "gru.pt", lambda tmp: torch.save(net.state_dict(), tmp))
    meta = {"network": "GRUPredictor (paper Fig. 5): 2-layer GRU, hidden 16, FC 16->2", "config": asdict(config),
            "unit_px": UNIT_PX, "train_windows": len(Xt), "val_windows": len(Xv),
            "val_position_error_px_after": {"gru": at(gru_err), "constant_velocity": at(cv_err), "hold": at(hold_err)},
            "history": history, "seconds": round(time.time() - t0, 1), "seeds": "simulator seeds 1000+ (benchmarks use 100-999)"}
    write_atomic(out_dir / "gru.json", json.dumps(meta, indent=2))
    return meta
