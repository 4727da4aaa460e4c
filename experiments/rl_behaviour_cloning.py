"""An RL example that learns: behaviour cloning of the IBVS expert from a Minari dataset, judged in the gym env.

    python experiments/rl_behaviour_cloning.py --out experiments/results/rl_behaviour_cloning

1. `hvs-sim dataset`'s recorder (hvs_sim.bench.dataset) writes TRAIN_EPISODES expert episodes (seeds 0…) from the
   servo benchmark's start poses (lateral ±10 cm, depth 0.7–1.4 × standoff, roll ±60°, pitch/yaw ±15°) in
   `hvs_sim/VisualServo-v1` with the "features" observation (the target's four corners and s*, joints as sin/cos);
2. the data is read back with `minari.load_dataset`, and a small MLP (torch) is fitted to the expert's actions;
3. every EVAL_EVERY epochs the policy drives the env from EVAL_EPISODES start poses of seeds it was not trained on
   (10 000…), and success (the env's is_success: mean corner error < 1 px held 5 steps) is counted beside the expert's
   on the same starts.

Writes summary.json (the learning curve, success with 95 % Wilson intervals, wall time) and learning_curve.png.
Seeded: two runs give the same figures. About 5 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

TRAIN_EPISODES, VAL_EPISODES = 60, 10
EVAL_EPISODES, EVAL_SEED0 = 30, 10_000
EPOCHS, EVAL_EVERY, BATCH, LR, HIDDEN = 150, 50, 256, 1e-3, 256
PIXEL_SCALE = 10.0  # px: the corner errors enter the network in tens of pixels
SEED = 0


def _inputs(obs: dict, size: np.ndarray) -> np.ndarray:
    """The policy's input: the corners' error to s* (tens of px), s* relative to the image, the joints' sin/cos, q̇."""
    f, d = np.asarray(obs["features"], np.float64), np.asarray(obs["desired"], np.float64)
    lead = f.shape[:-2]
    err = ((f - d) / PIXEL_SCALE).reshape(*lead, 8)
    rel = (d / size - 0.5).reshape(*lead, 8)
    return np.concatenate([err, rel, obs["joints"]], axis=-1).astype(np.float32)


def _policy(n_in: int) -> torch.nn.Module:
    return torch.nn.Sequential(torch.nn.Linear(n_in, HIDDEN), torch.nn.ReLU(), torch.nn.Linear(HIDDEN, HIDDEN),
                               torch.nn.ReLU(), torch.nn.Linear(HIDDEN, 6), torch.nn.Tanh())


def _episodes_to_arrays(episodes, size):
    x = np.concatenate([_inputs({k: v[:-1] for k, v in ep.observations.items()}, size) for ep in episodes])
    y = np.concatenate([ep.actions for ep in episodes]).astype(np.float32)
    return torch.from_numpy(x), torch.from_numpy(y)


def _rollouts(env, act, seeds) -> dict:
    """Episodes from the benchmark's start poses of `seeds`, driven by act(obs, info)."""
    from hvs_sim.bench.dataset import benchmark_start

    success, steps, final = [], [], []
    for seed in seeds:
        (obs, info), _ = benchmark_start(env, seed)
        done, n = False, 0
        while not done:
            obs, _, term, trunc, info = env.step(act(obs, info))
            done, n = term or trunc, n + 1
        success.append(bool(info["is_success"]))
        steps.append(n)
        final.append(float(info["error_px"]))
    return {"success": success, "steps": steps, "final_error_px": final}


def _rate(flags) -> dict:
    from hvs_sim.bench.stats import rate

    return rate(flags)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out/rl_behaviour_cloning")
    ap.add_argument("--epochs", type=int, default=EPOCHS)
    args = ap.parse_args()
    import minari

    import hvs_sim  # noqa: F401 - registers the env
    from hvs_sim.bench.dataset import DATASET_ID, DatasetConfig, record
    from hvs_sim.envs.expert import IBVSExpert
    from hvs_sim.outputs import write_atomic

    t0 = time.perf_counter()
    torch.manual_seed(SEED)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    config = DatasetConfig(episodes=TRAIN_EPISODES + VAL_EPISODES, seed=0)
    with tempfile.TemporaryDirectory() as root:
        recorded = record(config, root)
        os.environ["MINARI_DATASETS_PATH"] = root
        data = minari.load_dataset(DATASET_ID)
        episodes = list(data.iterate_episodes())
        env = data.recover_environment()
    t_data = time.perf_counter() - t0
    size = np.array([config.width, config.height], np.float64)
    x, y = _episodes_to_arrays(episodes[:TRAIN_EPISODES], size)
    xv, yv = _episodes_to_arrays(episodes[TRAIN_EPISODES:], size)
    net = _policy(x.shape[1])
    opt = torch.optim.Adam(net.parameters(), lr=LR)
    gen = torch.Generator().manual_seed(SEED)

    def act(obs, info):
        with torch.no_grad():
            return net(torch.from_numpy(_inputs(obs, size))[None])[0].numpy()

    eval_seeds = range(EVAL_SEED0, EVAL_SEED0 + EVAL_EPISODES)
    expert = _rollouts(env, IBVSExpert(env), eval_seeds)
    print(f"dataset: {recorded['episodes']} expert episodes, {recorded['steps']} steps ({t_data:.0f} s); expert on the "
          f"evaluation starts: {np.mean(expert['success']):.0%}")
    curve = []
    for epoch in range(1, args.epochs + 1):
        net.train()
        losses = []
        for idx in torch.randperm(len(x), generator=gen).split(BATCH):
            loss = torch.nn.functional.mse_loss(net(x[idx]), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            losses.append(loss.item())
        point = {"epoch": epoch, "train_mse": float(np.mean(losses))}
        if epoch == 1 or epoch % EVAL_EVERY == 0:
            net.eval()
            with torch.no_grad():
                point["val_mse"] = float(torch.nn.functional.mse_loss(net(xv), yv))
            run = _rollouts(env, act, eval_seeds)
            point.update(success=_rate(run["success"]), median_final_error_px=float(np.median(run["final_error_px"])),
                         median_steps=float(np.median(run["steps"])))
            print(f"epoch {epoch:4d}: train mse {point['train_mse']:.5f}, val {point['val_mse']:.5f}, success "
                  f"{point['success']['rate']:.0%} ({point['success']['ci95'][0]:.0%}–{point['success']['ci95'][1]:.0%}), "
                  f"median final error {point['median_final_error_px']:.2f} px")
        curve.append(point)
    env.close()
    last = [p for p in curve if "success" in p][-1]
    summary = {
        "what": "behaviour cloning of the IBVS expert (features observation) from a Minari dataset",
        "dataset": {k: recorded[k] for k in ("episodes", "steps", "success_rate", "dataset_id", "minari_version")},
        "train_episodes": TRAIN_EPISODES, "val_episodes": VAL_EPISODES,
        "eval": {"episodes": EVAL_EPISODES, "seeds": [EVAL_SEED0, EVAL_SEED0 + EVAL_EPISODES - 1],
                 "success_rule": "the env's is_success: mean corner error < 1 px (160×120) held 5 steps, within 300"},
        "policy": {"layers": [x.shape[1], HIDDEN, HIDDEN, 6], "epochs": args.epochs, "batch": BATCH, "lr": LR},
        "expert": {"success": _rate(expert["success"]), "median_steps": float(np.median(expert["steps"])),
                   "median_final_error_px": float(np.median(expert["final_error_px"]))},
        "final": last, "curve": curve, "wall_s": time.perf_counter() - t0, "torch_threads": torch.get_num_threads(),
    }
    write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    _figure(curve, summary["expert"]["success"]["rate"], out / "learning_curve.png")
    print(f"wall {summary['wall_s']:.0f} s; results: {out}/ (summary.json, learning_curve.png)")


def _figure(curve, expert_rate: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hvs_sim.outputs import temporary_beside

    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.4))
    a.semilogy([p["epoch"] for p in curve], [p["train_mse"] for p in curve], label="train")
    ev = [p for p in curve if "success" in p]
    a.semilogy([p["epoch"] for p in ev], [p["val_mse"] for p in ev], "o-", label="held-out episodes")
    a.set_xlabel("epoch")
    a.set_ylabel("action MSE")
    a.legend()
    b.errorbar([p["epoch"] for p in ev], [100 * p["success"]["rate"] for p in ev],
               yerr=[[100 * (p["success"]["rate"] - p["success"]["ci95"][0]) for p in ev],
                     [100 * (p["success"]["ci95"][1] - p["success"]["rate"]) for p in ev]], fmt="o-", capsize=3,
               label="cloned policy")
    b.axhline(100 * expert_rate, color="k", ls="--", label="IBVS expert")
    b.set_xlabel("epoch")
    b.set_ylabel("success on unseen starts (%)")
    b.set_ylim(-5, 105)
    b.legend(loc="lower right")
    fig.tight_layout()
    tmp = temporary_beside(path)
    fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


if __name__ == "__main__":
    main()
