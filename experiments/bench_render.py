"""Render-time benchmark: ms per 640×480 frame (RGB, and ground truth with occlusion) per mount and
per camera preset, and a figure of one frame through each preset.

    python experiments/bench_render.py --frames 100 --json experiments/results/render.json \
        --figure experiments/results/figures/camera_presets.png

`--supersample 2 3` also times the presets with each pixel the mean of k×k samples (CameraConfig.supersample), as
ratios to the same preset without; `--variants sharp small` also times each realistic preset without motion blur
(one render a frame: the least its light can cost) and with half-size sub-frames (`SensorModel.blur_subframe_scale`
2); `--figure ''` writes no figure. The presets (and their blur ways) are timed
interleaved, frame by frame in one process, so each one's whole frame over `ideal`'s (`ratio_to_ideal`) holds on a
busy machine; the JSON keeps the load average at the start and the end.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from hvs_sim.outputs import save_figure
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import SUPERSAMPLE_CHOICES, CameraConfig, make_scenario
from hvs_sim.scene.world import Scene
from hvs_sim.sensor import BLUR_MODES, SENSOR_NAMES, sensor_preset

FIGURE_FRAMES = (40, 78)  # walk_by hand-held seed 0: the camera drifting, and the person's edge crossing the target
CROP = (slice(150, 330), slice(300, 540))  # a zoom on the target and the person's edge


VARIANTS = {  # --variants: the same preset with these SensorModel settings, timed in the same interleaved run
    "sharp": {"blur_max_samples": 1},  # one render a frame, no motion blur: what the light costs at the least
    "small": {"blur_subframe_scale": 2},  # sub-frames at half size, the middle one's detail added (opt-in)
}


def time_presets(specs: dict[str, tuple], frames: int,
                 supersample: int = 1) -> tuple[dict[str, dict], dict[str, dict[int, np.ndarray]]]:
    """Median / p95 / mean ms of the RGB frame through each camera of `specs` (name: (preset, blur) or (preset, blur,
    {setting: value}), blur None for the preset's own; SensorModel.blur; the settings replace the preset's) over the first `frames` frames of walk_by, hand-held, seed 0, all timed
    INTERLEAVED: frame k of every camera in turn (the order rotated each frame), so that a busy or drifting machine
    slows them alike and their ratios hold in one run. With an `ideal` among them, each row has its whole frame's
    ratio to ideal's: of the means, and the median of the frame-by-frame ratios."""
    renderers, rows = {}, {}
    for name, (preset, blur, *settings) in specs.items():
        sensor = sensor_preset(preset, **({} if blur is None else {"blur": blur}), **(settings[0] if settings else {}))
        scene = Scene(make_scenario("walk_by", mount="handheld",
                                    camera=CameraConfig(sensor=sensor, supersample=supersample)))
        renderers[name] = Renderer(scene)
        rows[name] = {"ms": [], "stages": [], "samples": [], "taps": [], "kept": {}, "blur": sensor.blur}
    names = list(specs)
    for k in range(max(frames, max(FIGURE_FRAMES) + 1)):
        for name in names[k % len(names):] + names[:k % len(names)]:
            r, row = renderers[name], rows[name]
            t = time.perf_counter()
            frame = r.rgb()
            if k:  # frame 0 creates the GL context
                row["ms"].append(1e3 * (time.perf_counter() - t))
                row["stages"].append((r.stage_ms["light"], r.stage_ms["sensor"]))
            row["samples"].append(r.blur_samples)
            row["taps"].append(r.blur_taps)
            if k in FIGURE_FRAMES:
                row["kept"][k] = frame
            r.scene.advance()
    out, kept = {}, {}
    for name, row in rows.items():
        ms = np.asarray(row["ms"])
        light, electronics = np.mean(row["stages"], axis=0)
        samples, taps = np.asarray(row["samples"]), np.asarray(row["taps"])
        out[name] = {"rgb_ms_median": float(np.median(ms)), "rgb_ms_mean": float(ms.mean()),
                     "rgb_ms_p95": float(np.percentile(ms, 95)), "mean_blur_samples": float(samples.mean()),
                     # Renderer.stage_ms: the renders and what is done to the light, and the sensor's electronics
                     "light_ms_mean": float(light), "sensor_ms_mean": float(electronics), "blur": row["blur"],
                     "blurred_frames": int(np.count_nonzero(taps > 1) + np.count_nonzero(samples > 1))}
        kept[name] = row["kept"]
    if "ideal" in rows:
        ideal = np.asarray(rows["ideal"]["ms"])
        for name, p in out.items():
            p["ratio_to_ideal"] = p["rgb_ms_mean"] / float(ideal.mean())
            p["median_framewise_ratio_to_ideal"] = float(np.median(np.asarray(rows[name]["ms"]) / ideal))
            p["light_ratio_to_ideal"] = p["light_ms_mean"] / float(ideal.mean())
            p["sensor_ratio_to_ideal"] = p["sensor_ms_mean"] / float(ideal.mean())
    return out, kept


def time_preset(preset: str, frames: int, blur: str | None = None,
                supersample: int = 1) -> tuple[dict, dict[int, np.ndarray]]:
    """`time_presets` of one camera alone."""
    rows, kept = time_presets({preset: (preset, blur)}, frames, supersample)
    return rows[preset], kept[preset]


def preset_figure(frames: dict[str, dict[int, np.ndarray]], path: Path) -> None:
    """One row per preset: the two frames, and a zoom on the target area of the second."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(frames), 3, figsize=(13, 3.3 * len(frames)))  # the zoom is 4:3 like the frames
    for row, (preset, kept) in zip(np.atleast_2d(axes), frames.items()):
        a, b = (kept[k] for k in FIGURE_FRAMES)
        for ax, img, title in ((row[0], a, f"{preset}: frame {FIGURE_FRAMES[0]}"),
                               (row[1], b, f"{preset}: frame {FIGURE_FRAMES[1]}"),
                               (row[2], b[CROP], "zoom (1:1 pixels)")):
            ax.imshow(img, interpolation="nearest")
            ax.set_title(title, fontsize=9)
            ax.axis("off")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=80)  # written whole, through the output layer
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--json", default="experiments/results/render.json")
    ap.add_argument("--figure", default="experiments/results/figures/camera_presets.png")
    ap.add_argument("--presets", nargs="+", default=list(SENSOR_NAMES), choices=SENSOR_NAMES)
    ap.add_argument("--blur", nargs="+", default=list(BLUR_MODES), choices=BLUR_MODES,
                    help="motion blur ways to time each preset with (the first is the default's row)")
    ap.add_argument("--variants", nargs="*", default=[], choices=list(VARIANTS),
                    help="also time each realistic preset with these settings (VARIANTS), in the same run")
    ap.add_argument("--no-mounts", action="store_true", help="only the presets (not the mounts with and without shadows)")
    ap.add_argument("--supersample", type=int, nargs="*", default=[], choices=[k for k in SUPERSAMPLE_CHOICES if k > 1],
                    help="also time the presets supersampled k×k (their first blur way)")
    args = ap.parse_args()
    out = {"machine": platform.processor() or platform.machine(), "frames": args.frames, "interleaved": True,
           "load_average_at_start": list(os.getloadavg()), "camera_presets": {}}
    specs = {}
    for preset in args.presets:
        for k, blur in enumerate(args.blur if preset != "ideal" else args.blur[:1]):
            specs[preset if k == 0 else f"{preset}:{blur}"] = (preset, blur)
        for v in args.variants if preset != "ideal" else []:
            specs[f"{preset}:{v}"] = (preset, args.blur[0], VARIANTS[v])
    out["camera_presets"], got = time_presets(specs, args.frames)
    kept = {preset: got[preset] for preset in args.presets}
    out["load_average_at_end"] = list(os.getloadavg())
    realistic = [p for n, p in out["camera_presets"].items() if n != "ideal" and ":" not in n]
    if realistic and "ideal" in out["camera_presets"]:
        ideal_ms = out["camera_presets"]["ideal"]["rgb_ms_mean"]
        out["realistic_mean_ratio_to_ideal"] = float(np.mean([p["rgb_ms_mean"] for p in realistic]) / ideal_ms)
        # the same split: the renders and the light, and the sensor's electronics alone, each over ideal's frame
        out["realistic_mean_light_ratio_to_ideal"] = float(np.mean([p["light_ms_mean"] for p in realistic]) / ideal_ms)
        out["realistic_mean_sensor_ratio_to_ideal"] = float(np.mean([p["sensor_ms_mean"] for p in realistic]) / ideal_ms)
    for preset, p in out["camera_presets"].items():
        ratio = (f" ({p['ratio_to_ideal']:.2f}x ideal, frame by frame {p['median_framewise_ratio_to_ideal']:.2f}x)"
                 if "ratio_to_ideal" in p else "")
        print(f"camera {preset:26s} rgb median {p['rgb_ms_median']:.1f} ms, mean {p['rgb_ms_mean']:.1f} ms{ratio}, "
              f"p95 {p['rgb_ms_p95']:.1f} ms, {p['mean_blur_samples']:.2f} renders/frame, "
              f"{p['blurred_frames']} blurred frames; light {p['light_ms_mean']:.1f} ms + sensor "
              f"{p['sensor_ms_mean']:.1f} ms")
    if "realistic_mean_ratio_to_ideal" in out:
        print(f"realistic presets ({args.blur[0]} blur): mean render cost {out['realistic_mean_ratio_to_ideal']:.2f}x "
              f"ideal's: the renders and the light {out['realistic_mean_light_ratio_to_ideal']:.2f}x, the sensor's "
              f"electronics {out['realistic_mean_sensor_ratio_to_ideal']:.2f}x")
    for k in args.supersample:
        for preset in args.presets:
            plain = out["camera_presets"][preset]
            row, _ = time_preset(preset, args.frames, args.blur[0] if preset != "ideal" else None, supersample=k)
            row["ratio_to_plain"] = row["rgb_ms_mean"] / plain["rgb_ms_mean"]
            out.setdefault("supersampled", {})[f"{preset}:x{k}"] = row
            print(f"camera {preset:12s} supersampled {k}x{k}: rgb mean {row['rgb_ms_mean']:.1f} ms, "
                  f"{row['ratio_to_plain']:.2f}x the same preset without")
    if args.figure:
        preset_figure(kept, Path(args.figure))
    for mount in (() if args.no_mounts else ("handheld", "arm")):
        for shadows in (False, True):
            scene = Scene(make_scenario("walk_by", mount=mount, shadows=shadows))
            r = Renderer(scene)
            r.rgb()  # warm-up: context creation
            rgb_ms, gt_ms = [], []
            for _ in range(args.frames if not shadows else max(10, args.frames // 5)):
                t = time.perf_counter()
                r.rgb()
                rgb_ms.append(1e3 * (time.perf_counter() - t))
                t = time.perf_counter()
                r.ground_truth()
                gt_ms.append(1e3 * (time.perf_counter() - t))
                scene.advance()
            key = f"{mount}{'_shadows' if shadows else ''}"
            out[key] = {"rgb_ms_median": float(np.median(rgb_ms)), "rgb_ms_p95": float(np.percentile(rgb_ms, 95)),
                        "ground_truth_ms_median": float(np.median(gt_ms))}
            print(f"{key:18s} rgb median {out[key]['rgb_ms_median']:.1f} ms  p95 {out[key]['rgb_ms_p95']:.1f} ms  "
                  f"ground truth (2 segmentation renders) {out[key]['ground_truth_ms_median']:.1f} ms")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
