"""matplotlib figures of benchmark results (headless, Agg)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hvs_sim.outputs import save_figure, write_image
from hvs_sim.tracking.registry import TRACKERS

# one colour per tracker name, from the registry (distinct across methods and variants)
COLORS = {"ground_truth": "black", **{name: spec.colour for name, spec in TRACKERS.items()}}
# the servo benchmark's built-in method specs beyond the registry's names (TRACKER[:WARP][/CONTROLLER])
METHOD_COLORS = {"ground_truth/pbvs": "#636363", "hybrid:homography": "#8c0a0a", "hybrid:homography/pbvs": "#fd8d3c",
                 "none/dvs": "#31a354", "hybrid/pbvs": "#e6550d"}
# colours for any other spec (outside methods): picked by a stable hash of the spec, none of them the registry's
SPARE_COLORS = ("#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd", "#756bb1", "#636363",
                "#e7ba52", "#ad494a", "#a55194", "#6baed6", "#9e9ac8", "#74c476", "#fdae6b", "#969696")


def method_colour(spec: str) -> str:
    """One stable colour per method spec, in every figure: the registry's for its names, fixed ones for the servo
    benchmark's built-in specs, and for any other spec (a plugin) one picked by a hash of its text (the same in every
    run and process)."""
    import hashlib

    if spec in COLORS:
        return COLORS[spec]
    if spec in METHOD_COLORS:
        return METHOD_COLORS[spec]
    return SPARE_COLORS[int(hashlib.sha1(spec.encode()).hexdigest(), 16) % len(SPARE_COLORS)]


def track_triads(results: dict, config, out: Path) -> list[Path]:
    """Per scenario, the paper's Fig. 7 triad: CDF of e_xy, e_xy over time with occlusion, e_xy vs occlusion."""
    paths = []
    for scen in config.scenarios:
        keys = [k for k in results if k[0] == scen]
        if not keys:
            continue
        fig, ax = plt.subplots(1, 3, figsize=(16, 4.6))
        first = keys[0]
        for m in config.methods:
            err = np.concatenate([results[k][m]["error"][1:] for k in keys])
            occ = np.concatenate([results[k][m]["occlusion"][1:] for k in keys])
            c = method_colour(m)
            xs = np.sort(err)
            ax[0].plot(np.maximum(xs, 1e-3), np.arange(1, len(xs) + 1) / len(xs), label=m, color=c)
            r = results[first][m]
            ax[1].plot(np.arange(len(r["error"])), np.maximum(r["error"], 1e-3), label=m, color=c, lw=1.2)
            ax[2].scatter(100 * occ, np.maximum(err, 1e-3), s=5, alpha=0.5, label=m, color=c)
        occ0 = results[first][config.methods[0]]["occlusion"]
        twin = ax[1].twinx()
        twin.fill_between(np.arange(len(occ0)), 100 * occ0, color="grey", alpha=0.25, step="mid",
                          label="true occlusion (%)")
        twin.set_ylim(0, 100)
        twin.set_ylabel("true occlusion (%)")
        for a in ax[[0]]:
            a.axvline(2.0, ls="--", color="k", lw=0.8, label="2 px")
            a.set_xscale("log")
            a.set_xlabel("e_xy (px)")
            a.set_ylabel("fraction of frames ≤ e_xy")
            a.set_xlim(1e-2, 1e3)
        for a in ax[1:]:
            a.axhline(2.0, ls="--", color="k", lw=0.8, label="2 px")
            a.set_yscale("log")
            a.set_ylabel("e_xy (px)")
            a.set_ylim(1e-3, 2e3)
        ax[1].set_xlabel(f"frame ({first[1]}, seed {first[2]})")
        ax[2].set_xlabel("true occlusion (%)")
        ax[2].set_xlim(-2, 102)
        ax[0].legend(fontsize=8, loc="lower right")
        h1, l1 = ax[1].get_legend_handles_labels()
        h2, l2 = twin.get_legend_handles_labels()
        ax[1].legend([h1[-1], *h2], [l1[-1], *l2], fontsize=8, loc="upper right")  # the methods' colours: left panel
        ax[2].legend(fontsize=7, loc="upper left", markerscale=3, ncol=2)
        fig.suptitle(f"{scen}: CDF of e_xy | e_xy over time, occlusion shaded | e_xy vs occlusion")
        fig.tight_layout()
        p = Path(out) / f"fig7_{scen}.png"
        save_figure(fig, p, dpi=90)
        plt.close(fig)
        paths.append(p)
    return paths


def servo_figure(episodes: dict, out: Path, title: str) -> Path:
    """Error norm over time, image-plane corner trajectories, the camera's pose error (truth, with the
    largest condition number of L in the legend) and camera velocity, one example per method."""
    trackers = list(episodes)
    # the velocity panel shows one tracker: the hybrid when it ran, else the first that is not the oracle
    shown = "hybrid" if "hybrid" in trackers else next((t for t in trackers if t != "ground_truth"), trackers[0])
    fig, ax = plt.subplots(1, 4, figsize=(21, 4.6))
    for t in trackers:
        rec = episodes[t]
        c = method_colour(t)
        time = np.array([r["time"] for r in rec])
        ax[0].plot(time, np.maximum([r["error_px"] for r in rec], 1e-3), label=t, color=c)
        corners = np.array([r["gt_features"] for r in rec])
        for j in range(4):
            ax[1].plot(corners[:, j, 0], corners[:, j, 1], color=c, lw=1, label=t if j == 0 else None)
        if rec and "pose_error" in rec[0]:
            pe = np.array([r["pose_error"] for r in rec])
            conds = [r["condition"] for r in rec if r.get("condition")]
            cond = f", cond(L) ≤ {max(conds):.0f}" if conds else ""
            ax[2].plot(time, np.maximum(np.linalg.norm(pe[:, :3], axis=1), 1e-3), color=c, label=f"{t} (mm{cond})")
            ax[2].plot(time, np.maximum(np.linalg.norm(pe[:, 3:], axis=1), 1e-3), color=c, ls="--", label=f"{t} (°)")
        if t == shown:
            twist = np.array([r["twist"] for r in rec])
            for j, n in enumerate(("vx", "vy", "vz", "wx", "wy", "wz")):
                ax[3].plot(time, twist[:, j], label=n)
            occ = np.array([r["occlusion"] for r in rec])
            ax[0].fill_between(time, 1e-3, np.where(occ > 0, 1e3, 1e-3), color="grey", alpha=0.2, step="mid",
                               label="target occluded")
    desired = np.array(episodes[trackers[0]][0]["desired"])
    ax[1].scatter(desired[:, 0], desired[:, 1], marker="x", s=80, color="k", label="s*", zorder=5)
    ax[0].axhline(0.5, ls="--", color="k", lw=0.8, label="converged below 0.5 px")
    ax[0].set_yscale("log")
    ax[0].set_ylim(1e-2, 2e2)
    ax[0].set_xlabel("time (s)")
    ax[0].set_ylabel("mean corner error to s* (px, ground truth)")
    ax[0].legend(fontsize=8)
    ax[1].invert_yaxis()
    ax[1].set_aspect("equal")
    ax[1].set_xlabel("u (px)")
    ax[1].set_ylabel("v (px)")
    ax[1].set_title("true corner trajectories")
    ax[1].legend(fontsize=8)
    ax[2].set_yscale("log")
    ax[2].set_xlabel("time (s)")
    ax[2].set_ylabel("camera pose error to the reference (mm solid, ° dashed)")
    ax[2].set_title("pose error (simulator truth)")
    ax[2].legend(fontsize=7)
    ax[3].set_xlabel("time (s)")
    ax[3].set_ylabel("camera twist (m/s, rad/s)")
    ax[3].set_title(f"camera velocity ({shown})")
    ax[3].legend(fontsize=8, ncol=2)
    fig.suptitle(title)
    fig.tight_layout()
    p = Path(out)
    save_figure(fig, p, dpi=90)
    plt.close(fig)
    return p


def _overlay(r) -> np.ndarray:
    """One closed-loop frame, BGR, half size: the outline the controller used (thick green: tracked, through the
    feature filter when it is on) under the true (white) and desired (red) outlines, so all three stay visible
    where they coincide."""
    import cv2

    img = cv2.cvtColor(r.frame, cv2.COLOR_RGB2BGR)
    for pts, col, width in ((r.features, (0, 255, 0), 6), (r.gt_features, (255, 255, 255), 2),
                            (r.desired, (60, 60, 255), 2)):
        if np.all(np.isfinite(pts)):
            cv2.polylines(img, [np.round(pts * 16).astype(np.int32)], True, col, width, cv2.LINE_AA, shift=4)
    img = cv2.resize(img, (480, 360), interpolation=cv2.INTER_AREA)
    occl = "" if np.isnan(r.occlusion) else f" occl. {r.occlusion:.0%}"
    label = f"t={r.time:.2f}s {r.mode}{occl} err {r.error_px:.2f}px"
    cv2.rectangle(img, (0, 0), (480, 30), (0, 0, 0), -1)
    cv2.putText(img, label, (8, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def run_figures(picks: list, series: dict, summary: dict, out: Path, converge_px: float = 0.5) -> list[Path]:
    """Beside a closed-loop run: `frames.png` (the four picked records with their frames: start, occlusion
    rising, peak occlusion, end (runner.FramePicks), with the tracked / true / desired outlines) and
    `error.png` (errors over time from RunStats.series, predicted steps and true occlusion shaded)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tiles = [_overlay(r) for r in picks]
    frames = out / "frames.png"
    write_image(frames, np.vstack([np.hstack(tiles[:2]), np.hstack(tiles[2:])]))
    t, occ = series["time"], np.nan_to_num(series["occlusion"])
    fig, (ax, pax) = plt.subplots(2, 1, figsize=(9, 6.4), sharex=True, height_ratios=(3, 2))
    ax.semilogy(t, np.maximum(series["error_px"], 1e-3), color="tab:red", label="ground-truth error to s* (px)")
    ax.semilogy(t, np.maximum(series["tracker_error_px"], 1e-3), color="tab:green", label="tracker corner error (px)")
    ax.axhline(converge_px, ls="--", color="k", lw=0.8, label=f"converged below {converge_px:g} px")
    pred = series["predict"]
    ax.fill_between(t, 1e-3, 1e3, where=pred, color="tab:blue", alpha=0.15, step="mid",
                    label="predicted (scene motion / GRU)")
    tw = ax.twinx()
    tw.fill_between(t, 0, 100 * occ, color="grey", alpha=0.3, step="mid", label="true occlusion (%)")
    tw.set_ylabel("true occlusion (%)")
    tw.set_ylim(0, 100)
    ax.set_ylim(1e-2, 1e2)
    pose = summary.get("pose_bound")
    if pose and "pose_mm" in series:  # the pose error in the controlled DOFs against its bound
        pax.semilogy(t, np.maximum(series["pose_mm"], 1e-3), color="tab:purple", label="pose error (mm)")
        pax.semilogy(t, np.maximum(series["pose_deg"], 1e-4), color="tab:orange", label="pose error (°)")
        pax.axhline(pose["mm"], ls="--", color="tab:purple", lw=0.8, label=f"bound {pose['mm']:g} mm")
        pax.axhline(pose["deg"], ls=":", color="tab:orange", lw=0.8, label=f"bound {pose['deg']:g}°")
        pax.set_ylabel(f"pose error in {len(pose['applies_to'])} DOFs")
        pax.legend(fontsize=8, loc="upper right", ncol=2)
    pax.set_xlabel("time (s)")
    handles = ax.get_legend_handles_labels()
    extra = tw.get_legend_handles_labels()
    ax.legend(handles[0] + extra[0], handles[1] + extra[1], fontsize=8, loc="upper right")
    ax.set_title(f"{summary['scenario']} / {summary['tracker']}: final error {summary['final_error_px']:.2f} px, "
                 f"{'converged' if summary.get('held_to_end', summary['converged']) else 'not converged'}"
                 + ("" if summary.get("held_to_end", True) else f" ({summary['not_converged_because']})"), fontsize=9)
    fig.tight_layout()
    error = out / "error.png"
    try:
        save_figure(fig, error, dpi=100)
    finally:
        plt.close(fig)
    return [frames, error]
