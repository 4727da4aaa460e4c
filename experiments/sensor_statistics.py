"""The camera model's statistics, measured: noise variance per brightness level against `output_variance`'s formula,
JPEG blockiness on a rendered frame, the motion blur's edge profile, whole frames of a `phone_handheld` walk_by run
and the hybrid's error on them. Run it once with an older checkout's package to keep its figures, then with this one
to compare (issue 56: the sensor made cheaper must keep its statistics):

    git archive <old commit> hvs_sim | tar -x -C /tmp/before
    PYTHONPATH=/tmp/before python experiments/sensor_statistics.py --label before \
        --json /tmp/before/stats.json --frames-npz /tmp/before/frames.npz
    python experiments/sensor_statistics.py --label after --before /tmp/before/stats.json \
        --before-frames /tmp/before/frames.npz --out experiments/results/sensor_statistics

The script reads the public API only (present in both), so the same file measures either package. `--subframe-scale 2`
takes `phone_handheld` with `SensorModel.blur_subframe_scale` 2 (the half-size sub-frames; this package only). With --out it
writes stats.json (both labels and their differences) and statistics.png there.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from hvs_sim.outputs import save_figure
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.scene.world import Scene
from hvs_sim.sensor import SensorState, encode, output_variance, sensor_preset

LEVELS = np.round(np.geomspace(0.03, 0.9, 12), 4)  # linear radiance of the flat fields
FLAT_SIZE = (240, 320)  # one flat field: 230 400 samples a level and preset
NOISE_PRESETS = ("webcam", "phone_handheld", "robot_cell", "low_light")
BLOCK = 8  # JPEG's DCT block
RUN_FRAMES = 100  # walk_by hand-held, seed 0, through phone_handheld: the frames compared pixel by pixel
TRACK_FRAMES = 150  # the hybrid's error on a phone_handheld walk_by sequence (seed 100)


def noise_by_level() -> dict:
    """Per preset (JPEG off, gain fixed at 1) and level: the measured variance of the 8-bit output and the formula's."""
    out = {}
    for name in NOISE_PRESETS:
        model = sensor_preset(name, jpeg_quality=0, ae_target=0.0)
        state = SensorState(model, 11, FLAT_SIZE)
        rows = []
        for k, level in enumerate(LEVELS):
            frame = state.capture(np.full((*FLAT_SIZE, 3), level, np.float32), k, 0.0, 1 / 30).astype(np.float64)
            rows.append({"level": float(level), "mean": float(frame.mean()), "variance": float(frame.var()),
                         "formula": float(output_variance(model, np.float32(level), 1.0))})
        out[name] = rows
    return out


def blockiness(frame: np.ndarray) -> float:
    """Mean |luma step| across 8×8 block boundaries over the mean |step| inside blocks (1: no block edges)."""
    y = cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY).astype(np.float64)
    dx, dy = np.abs(np.diff(y, axis=1)), np.abs(np.diff(y, axis=0))
    at_x = (np.arange(dx.shape[1]) % BLOCK) == BLOCK - 1
    at_y = (np.arange(dy.shape[0]) % BLOCK) == BLOCK - 1
    across = np.concatenate([dx[:, at_x].ravel(), dy[at_y].ravel()]).mean()
    inside = np.concatenate([dx[:, ~at_x].ravel(), dy[~at_y].ravel()]).mean()
    return float(across / inside)


def edge_profile(frame: np.ndarray) -> list[float]:
    """The mean luma across the strongest vertical edge in the target's area (rows 150–330, columns 300–540), ±12 px."""
    y = cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY).astype(np.float64)[150:330, 300:540]
    col = 12 + int(np.argmax(np.abs(np.diff(y.mean(axis=0)))[12:-12]))
    return y[:, col - 12: col + 13].mean(axis=0).round(3).tolist()


def phone(subframe_scale: int | None = None):
    """The `phone_handheld` camera: the preset's name, or the preset with blur_subframe_scale replaced."""
    return "phone_handheld" if subframe_scale is None else sensor_preset("phone_handheld",
                                                                         blur_subframe_scale=subframe_scale)


def walk_by_run(subframe_scale: int | None = None) -> tuple[np.ndarray, dict]:
    """RUN_FRAMES frames of walk_by hand-held through phone_handheld, and figures of them."""
    r = Renderer(Scene(make_scenario("walk_by", mount="handheld", camera=CameraConfig(sensor=phone(subframe_scale)))))
    frames, samples, lights = [], [], []
    for _ in range(RUN_FRAMES):
        frames.append(r.rgb())
        samples.append(r.blur_samples)
        lights.append(r.linear_light() if samples[-1] == max(samples) else None)  # the most blurred frame's light
        r.scene.advance()
    frames, blurred = np.stack(frames), int(np.argmax(samples))
    return frames, {
        "blockiness_mean": float(np.mean([blockiness(f) for f in frames])),
        "blurred_frame": blurred, "blur_samples": int(samples[blurred]),
        "edge_profile": edge_profile(frames[blurred]),
        "light_profile": edge_profile(encode(lights[blurred])),  # the blur alone: before noise and JPEG
        "frame_means": frames.reshape(len(frames), -1).mean(axis=1).round(4).tolist(),
    }


def hybrid_error(subframe_scale: int | None = None) -> dict:
    from hvs_sim.bench.sequences import make_sequence
    from hvs_sim.bench.track import run_tracker

    seq = make_sequence(make_scenario("walk_by", mount="handheld", seed=100,
                                      camera=CameraConfig(sensor=phone(subframe_scale))), n_frames=TRACK_FRAMES)
    err = run_tracker("hybrid", seq)["error"][1:]
    return {"frames": len(err), "median_px": float(np.median(err)), "mean_px": float(np.mean(err)),
            "within_2px": float(np.mean(err <= 2.0)), "error_px": err.round(4).tolist()}


def compare(before: dict, after: dict, frames_before: np.ndarray | None, frames_after: np.ndarray) -> dict:
    rel = [abs(a["variance"] / b["variance"] - 1) for p in NOISE_PRESETS
           for a, b in zip(after["noise"][p], before["noise"][p])]
    out = {"noise_variance_max_relative_change": float(max(rel)),
           "blockiness_mean": [before["run"]["blockiness_mean"], after["run"]["blockiness_mean"]],
           "edge_profile_max_abs_change": float(np.max(np.abs(np.subtract(before["run"]["edge_profile"],
                                                                         after["run"]["edge_profile"])))),
           "light_profile_max_abs_change": float(np.max(np.abs(np.subtract(
               before["run"]["light_profile"], after["run"]["light_profile"])))),
           "hybrid_median_px": [before["track"]["median_px"], after["track"]["median_px"]],
           "hybrid_within_2px": [before["track"]["within_2px"], after["track"]["within_2px"]],
           "hybrid_max_framewise_error_change_px": float(np.max(np.abs(np.subtract(before["track"]["error_px"],
                                                                                   after["track"]["error_px"]))))}
    if frames_before is not None:
        d = np.abs(frames_before.astype(np.int16) - frames_after.astype(np.int16))
        out["frames_pixels_differing"] = float(np.mean(d > 0))
        out["frames_max_abs_difference"] = int(d.max())
        out["frames_mean_abs_difference"] = float(d.mean())
    return out


def figure(before: dict, after: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    ax = axes[0]
    for k, p in enumerate(NOISE_PRESETS):
        c = f"C{k}"
        ax.plot(LEVELS, [r["formula"] for r in after["noise"][p]], "-", color=c, lw=1, label=f"{p}: formula")
        ax.plot(LEVELS, [r["variance"] for r in before["noise"][p]], "o", color=c, mfc="none", ms=7)
        ax.plot(LEVELS, [r["variance"] for r in after["noise"][p]], "x", color=c, ms=5)
    ax.set(xscale="log", yscale="log", xlabel="linear level (flat field)", ylabel="output variance (8-bit levels²)",
           title="noise per level: o before, x after, line output_variance")
    ax.legend(fontsize=7)
    ax = axes[1]
    for lab, res, st in (("before", before, "o-"), ("after", after, "x--")):
        ax.plot(res["track"]["error_px"], st, ms=2, lw=0.8, label=f"{lab}: median {res['track']['median_px']:.2f} px")
    ax.set(xlabel="frame", ylabel="hybrid error (px)", yscale="log",
           title="hybrid on phone_handheld walk_by (seed 100)")
    ax.legend(fontsize=8)
    ax = axes[2]
    x = np.arange(-12, 13)
    for lab, res, st in (("before", before, "o-"), ("after", after, "x--")):
        ax.plot(x, res["run"]["edge_profile"], st, ms=4,
                label=f"{lab}: frame {res['run']['blurred_frame']} ({res['run']['blur_samples']} sub-frames), "
                      f"blockiness {res['run']['blockiness_mean']:.3f}")
    ax.set(xlabel="px across the edge", ylabel="mean luma", title="the most blurred frame's edge, as delivered")
    ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=90)  # written whole, through the output layer
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--label", default="after")
    ap.add_argument("--json", help="this package's figures alone")
    ap.add_argument("--frames-npz", help="save the walk_by run's frames here (for a later --before-frames)")
    ap.add_argument("--before", help="an earlier run's --json, to compare with")
    ap.add_argument("--before-frames", help="an earlier run's --frames-npz")
    ap.add_argument("--out", help="folder for stats.json and statistics.png (with --before)")
    ap.add_argument("--subframe-scale", type=int, help="phone_handheld's blur_subframe_scale (default: the preset's)")
    args = ap.parse_args()
    frames, run = walk_by_run(args.subframe_scale)
    res = {"label": args.label, "noise": noise_by_level(), "run": run, "track": hybrid_error(args.subframe_scale)}
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2))
    if args.frames_npz:
        np.savez_compressed(args.frames_npz, frames=frames)
    print(f"{args.label}: blockiness {run['blockiness_mean']:.4f}, hybrid median {res['track']['median_px']:.3f} px")
    if args.before and args.out:
        before = json.loads(Path(args.before).read_text())
        frames_before = np.load(args.before_frames)["frames"] if args.before_frames else None
        cmp = compare(before, res, frames_before, frames)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "stats.json").write_text(json.dumps({"before": before, "after": res, "comparison": cmp}, indent=2))
        figure(before, res, out / "statistics.png")
        print(json.dumps(cmp, indent=2))


if __name__ == "__main__":
    main()
