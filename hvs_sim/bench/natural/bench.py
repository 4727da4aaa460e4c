"""The benchmark: every method on every (source, kind, seed) sequence, in worker processes (`_natural_job`), and its
outputs (summary.json, frames.csv, table.md, fig_natural.png, sequences.png)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from hvs_sim.bench.natural.picture import MOTIONS
from hvs_sim.bench.natural.sequence import NaturalSequence, make_natural_sequence
from hvs_sim.bench.natural.sources import ALL_KINDS, DEFAULT_SEEDS, NATURAL_KINDS, NATURAL_SOURCES, OCCLUDED_KINDS
from hvs_sim.bench.pool import collect_jobs, config_json, write_frames_csv
from hvs_sim.errors import ConfigError, choice_error
from hvs_sim.outputs import save_figure, write_atomic
from hvs_sim.sensor import REALISTIC_PRESET, sensor_preset

# ---------------------------------------------------------------------------------------------------------------------
# The benchmark
# ---------------------------------------------------------------------------------------------------------------------

VISIBLE_BELOW = 0.4  # the visible_lt_40 split: frames with true occlusion < 40 %
PREVIEW_SCALE = 0.5  # contact-sheet thumbnails
SHEET_SEQUENCES = 6
TIMING_REFERENCE = "ecc"


@dataclass(frozen=True)
class NaturalBenchConfig:
    methods: tuple[str, ...] = ("ecc", "deep_lk", "hybrid")
    sources: tuple[str, ...] = NATURAL_SOURCES
    kinds: tuple[str, ...] = NATURAL_KINDS
    seeds: tuple[int, ...] = DEFAULT_SEEDS
    frames: int = 150
    camera: str = REALISTIC_PRESET
    workers: int = 1
    threads: int = 1  # torch threads per process: timings on a shared machine stay comparable
    motion: str = "hand"  # MOTIONS

    def __post_init__(self):
        if self.motion not in MOTIONS:
            raise choice_error("natural motion", self.motion, tuple(MOTIONS))
        for s in self.sources:
            if s not in NATURAL_SOURCES:
                raise choice_error("natural source", s, NATURAL_SOURCES)
        for k in self.kinds:
            if k not in ALL_KINDS:
                raise choice_error("natural kind", k, ALL_KINDS)
        from hvs_sim.tracking import TRACKER_NAMES

        for m in self.methods:
            if m not in TRACKER_NAMES:
                raise choice_error("tracker", m, TRACKER_NAMES)
        sensor_preset(self.camera)
        if not self.methods or not self.sources or not self.kinds or not self.seeds:
            raise ConfigError("natural benchmark needs at least one method, source, kind and seed")


def _previews(seq: NaturalSequence) -> tuple[np.ndarray, np.ndarray, int]:
    """Frame 0 with the ROI, and the frame of peak occlusion (the last frame if none) with the true target position,
    half size."""
    gt = seq.gt_track
    f0 = seq.frames[0].copy()
    x, y, w, h = seq.roi
    cv2.rectangle(f0, (x, y), (x + w - 1, y + h - 1), (0, 255, 0), 2)
    k = int(np.argmax(seq.occlusion)) if seq.occlusion.max() > 0 else len(seq.frames) - 1
    fk = seq.frames[k].copy()
    cv2.drawMarker(fk, tuple(round(v) for v in gt[k]), (0, 255, 0), cv2.MARKER_CROSS, 24, 2)
    small = [cv2.resize(f, None, fx=PREVIEW_SCALE, fy=PREVIEW_SCALE, interpolation=cv2.INTER_AREA) for f in (f0, fk)]
    return small[0], small[1], k


def _natural_job(args):
    import torch

    from hvs_sim.bench.track import run_tracker

    source, kind, seed, frames, methods, camera, threads, motion = args
    torch.set_num_threads(threads)
    seq = make_natural_sequence(source, kind, seed, n_frames=frames, camera=camera, motion=motion)
    res = {m: run_tracker(m, seq) for m in methods}
    f0, fk, k = _previews(seq)
    meta = {"roi": list(seq.roi), "generate_s": seq.seconds, "peak_occlusion": float(seq.occlusion.max()),
            "frames_occluded_ge_90": int(np.sum(seq.occlusion >= 0.9)), "peak_frame": k,
            "max_gt_step_px": float(np.linalg.norm(np.diff(seq.gt_track, axis=0), axis=1).max()),
            "blur_samples_mean": float(seq.blur_samples.mean()), "preview": (f0, fk)}
    return (source, kind, seed), res, meta


def run_natural_bench(config: NaturalBenchConfig, out: Path, progress: bool = True, resume: bool = False) -> dict:
    """Every method on every (source, kind, seed) sequence; writes summary.json, frames.csv, table.md and figures."""

    from hvs_sim.bench.track import summarize

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(s, k, seed, config.frames, config.methods, config.camera, config.threads, config.motion)
            for s in config.sources for k in config.kinds for seed in config.seeds]
    results, metas = {}, {}
    for key, res, meta in collect_jobs(_natural_job, jobs, config, out, "bench natural", "sequence", progress, resume):
        results[key], metas[key] = res, meta

    def label(key) -> str:
        return f"{key[0]}/{key[1]}/s{key[2]}"

    def visible(r):
        return r["occlusion"] < VISIBLE_BELOW

    summary = {"config": config_json(config),
               "per_sequence": {}, "per_kind": {}, "overall": {}, "visible_lt_40": {}, "unoccluded_sequences": {},
               "timing": {}, "generation": {}}
    for key in results:
        meta = {k: v for k, v in metas[key].items() if k != "preview"}
        summary["per_sequence"][label(key)] = {**meta, "methods": {m: summarize([results[key][m]]) for m in config.methods}}
    for m in config.methods:
        rs = [results[k][m] for k in results]
        summary["overall"][m] = summarize(rs)
        summary["visible_lt_40"][m] = summarize(rs, visible)
        for kind in config.kinds:
            summary["per_kind"].setdefault(kind, {})[m] = summarize([results[k][m] for k in results if k[1] == kind])
        clear = [results[k][m] for k in results if k[1] == "clear"]
        if clear:
            err = np.concatenate([r["error"][1:] for r in clear])
            summary["unoccluded_sequences"][m] = {"sequences": len(clear), "frames": int(err.size),
                                                  "max_px": float(err.max()), "frames_gt_2px": int(np.sum(err > 2.0))}
    ref = summary["overall"].get(TIMING_REFERENCE, {}).get("median_ms")
    for m in config.methods:
        med = summary["overall"][m]["median_ms"]
        summary["timing"][m] = {"median_ms": med, f"ratio_to_{TIMING_REFERENCE}": (med / ref) if ref else None}
    gen = np.array([metas[k]["generate_s"] for k in metas])
    summary["generation"] = {"sequences": int(gen.size), "median_s": float(np.median(gen)), "max_s": float(gen.max()),
                             "frames_per_sequence": config.frames}
    write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    write_frames_csv(results, out / "frames.csv", ("source", "kind", "seed"))
    write_atomic(out / "table.md", natural_table(summary))
    natural_figures(results, metas, config, out)
    return summary


def natural_table(summary: dict) -> str:
    """table.md: overall, visible frames, per kind, per sequence (≤2 px %), timing against ECC."""
    head = ["| method | frames | ≤1 px | ≤2 px | median px | p95 px | max px | median ms | lost | predict |",
            "|---|---|---|---|---|---|---|---|---|---|"]

    def row(name, s):
        if not s.get("frames"):
            return f"| {name} | 0 | | | | | | | | |"
        return (f"| {name} | {s['frames']} | {s['pct_le_1px']:.1f} % | {s['pct_le_2px']:.1f} % | {s['median_px']:.2f} | "
                f"{s['p95_px']:.2f} | {s['max_px']:.1f} | {s['median_ms']:.1f} | {s['pct_lost']:.1f} % | "
                f"{s['pct_predict']:.1f} % |")

    cfg = summary["config"]
    intro = (f"Natural imagery: {len(cfg['sources'])} sources × kinds {', '.join(cfg['kinds'])} × seeds "
             f"{', '.join(map(str, cfg['seeds']))}, {cfg['frames']} frames, camera {cfg['camera']}.")
    text = [intro, "",
            "## All sequences, all frames", "", *head, *[row(m, v) for m, v in summary["overall"].items()],
            "", "## Frames with true occlusion < 40 %", "", *head,
            *[row(m, v) for m, v in summary["visible_lt_40"].items()]]
    for kind, per in summary["per_kind"].items():
        text += ["", f"## {kind}", "", *head, *[row(m, v) for m, v in per.items()]]
    if summary["unoccluded_sequences"]:
        text += ["", "## Unoccluded sequences (clear): worst error", "", "| method | sequences | frames | max px | frames > 2 px |",
                 "|---|---|---|---|---|"]
        text += [f"| {m} | {v['sequences']} | {v['frames']} | {v['max_px']:.2f} | {v['frames_gt_2px']} |"
                 for m, v in summary["unoccluded_sequences"].items()]
    methods = list(summary["overall"])
    text += ["", "## Per sequence: ≤2 px % (peak true occlusion)", "",
             "| sequence | peak occ. | " + " | ".join(methods) + " |", "|---|---|" + "---|" * len(methods)]
    for name, s in summary["per_sequence"].items():
        cells = [f"{s['methods'][m]['pct_le_2px']:.0f}" for m in methods]
        if "hybrid" in methods:  # bold where the hybrid is behind another method
            best = max(s["methods"][m]["pct_le_2px"] for m in methods)
            i = methods.index("hybrid")
            if s["methods"]["hybrid"]["pct_le_2px"] < best:
                cells[i] = f"**{cells[i]}**"
        text.append(f"| {name} | {100 * s['peak_occlusion']:.0f} % | " + " | ".join(cells) + " |")
    text += ["", f"## Timing (median ms per frame; ratio to {TIMING_REFERENCE} in the same run)", "",
             f"| method | median ms | × {TIMING_REFERENCE} |", "|---|---|---|"]
    for m, v in summary["timing"].items():
        ratio = v[f"ratio_to_{TIMING_REFERENCE}"]
        text.append(f"| {m} | {v['median_ms']:.1f} | {'' if ratio is None else f'{ratio:.2f}'} |")
    g = summary["generation"]
    gen = (f"Generation: median {g['median_s']:.1f} s (max {g['max_s']:.1f} s) per sequence of "
           f"{g['frames_per_sequence']} frames.")
    text += ["", gen]
    return "\n".join(text) + "\n"


def _sheet_keys(keys: list, n: int) -> list:
    """Sequences for the contact sheet: one per kind, then more occluded ones; each from a new source while any is left."""
    chosen, sources = [], set()
    all_sources = {q[0] for q in keys}

    def take(k) -> None:
        chosen.append(k)
        sources.add(k[0])

    for kind in (*OCCLUDED_KINDS, "clear"):
        for k in keys:
            if k[1] == kind and (k[0] not in sources or sources == all_sources):
                take(k)
                break
    for occluded in (True, False):
        for k in keys:
            if len(chosen) < n and k not in chosen and (k[1] != "clear") == occluded \
                    and (k[0] not in sources or sources == all_sources):
                take(k)
    return chosen[:n]


def natural_figures(results: dict, metas: dict, config: NaturalBenchConfig, out: Path) -> list[Path]:
    """fig_natural.png (CDF of the error per method: all, per kind, visible frames) and sequences.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hvs_sim.viz.figures import method_colour

    panels = [("all frames", list(results), None)] + [(k, [q for q in results if q[1] == k], None) for k in config.kinds]
    panels.append((f"occlusion < {VISIBLE_BELOW:.0%}", list(results), VISIBLE_BELOW))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.0), squeeze=False)
    for ax, (title, keys, below) in zip(axes[0], panels):
        for m in config.methods:
            errs = [results[k][m]["error"][1:] if below is None else
                    results[k][m]["error"][1:][results[k][m]["occlusion"][1:] < below] for k in keys]
            err = np.concatenate(errs) if errs else np.array([])
            if err.size:
                xs = np.sort(err)
                ax.plot(np.maximum(xs, 1e-3), np.arange(1, xs.size + 1) / xs.size, label=m, color=method_colour(m))
        ax.axvline(2.0, ls="--", color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlim(1e-2, 1e3)
        ax.set_ylim(0, 1)
        ax.set_xlabel("error (px)")
        ax.set_title(title)
    axes[0][0].set_ylabel("fraction of frames ≤ error")
    axes[0][0].legend(fontsize=8, loc="upper left")
    fig.suptitle(f"Natural imagery ({config.camera}): CDF of the tracking error")
    fig.tight_layout()
    p1 = Path(out) / "fig_natural.png"
    save_figure(fig, p1, dpi=90)
    plt.close(fig)

    keys = _sheet_keys(list(results), SHEET_SEQUENCES)
    fig, axes = plt.subplots(len(keys), 2, figsize=(8, 3.1 * len(keys)), squeeze=False)
    for row, k in zip(axes, keys):
        f0, fk = metas[k]["preview"]
        row[0].imshow(f0)
        row[0].set_title(f"{k[0]} {k[1]} s{k[2]}: frame 0, ROI", fontsize=9)
        row[1].imshow(fk)
        what = (f"peak occlusion {100 * metas[k]['peak_occlusion']:.0f} %" if metas[k]["peak_occlusion"] > 0
                else "last frame")
        row[1].set_title(f"frame {metas[k]['peak_frame']}: {what}, true centre", fontsize=9)
        for a in row:
            a.axis("off")
    fig.tight_layout()
    p2 = Path(out) / "sequences.png"
    save_figure(fig, p2, dpi=80)
    plt.close(fig)
    return [p1, p2]


def smoke_config(methods: tuple[str, ...], camera: str = REALISTIC_PRESET, workers: int = 1) -> NaturalBenchConfig:
    """A tiny run that checks the pipeline end to end: one source, walk_by, 40 frames. Not a result."""
    return NaturalBenchConfig(methods=methods, sources=NATURAL_SOURCES[:1], kinds=("walk_by",), seeds=DEFAULT_SEEDS[:1],
                              frames=40, camera=camera, workers=workers)
