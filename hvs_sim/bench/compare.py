"""`hvs-sim bench compare A B`: two servo results of the same suite, compared episode by episode.

Each pair (a method of A, a method of B) is compared on the episodes both ran (same scenario, same seed, hence the
same start pose and the same people): McNemar's exact test on the hvs_sim success rule's verdicts, and Wilcoxon's
signed-rank test on the final pose error (mm) and the final image error (px), each with its p-value. Results of
different suites, suite versions or suite-defining settings are refused: their episodes are not the same.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hvs_sim.bench.suites import TILT_MAX_DEG
from hvs_sim.errors import ConfigError

# the settings that make two runs' episodes the same ones (ServoBenchConfig fields)
EPISODE_FIELDS = ("scenarios", "camera", "people", "width", "height", "tilt_deg", "extra_steps", "steps", "success_px",
                  "arm")


def load_results(folder) -> dict:
    path = Path(folder) / "summary.json"
    if not path.is_file():
        raise ConfigError(f"{folder} holds no summary.json: give a folder written by `hvs-sim bench servo`")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{path} cannot be read as JSON ({exc})") from None
    if isinstance(data, dict) and data.get("interrupted"):  # said first: such a summary has no schema yet
        raise ConfigError(f"{path} is an interrupted run's partial summary ({data.get('completed_jobs', '?')} of "
                          f"{data.get('total_jobs', '?')} episodes finished): run it again to the end first")
    if not isinstance(data, dict) or not str(data.get("schema", "")).startswith("hvs_sim.servo-results/2"):
        raise ConfigError(f"{path} is not a servo benchmark summary of schema hvs_sim.servo-results/2 (it lacks the "
                          "per-episode records the rules need; results from before the suites cannot be compared): "
                          "run the suite again")
    if not isinstance(data.get("episodes"), list) or "config" not in data:
        raise ConfigError(f"{path} is not a servo benchmark's summary (no episodes): compare works on `bench servo` "
                          "results")
    return data


def _check_same(a: dict, b: dict, names: tuple[str, str]) -> None:
    sa, sb = a.get("suite"), b.get("suite")
    if sa != sb:
        raise ConfigError(f"{names[0]} is suite {sa!r} and {names[1]} is suite {sb!r}: only results of one suite and "
                          "version compare episode by episode")
    for key in EPISODE_FIELDS:
        va, vb = a["config"].get(key), b["config"].get(key)
        if key == "tilt_deg":  # results before the field existed drew the 6-DOF tilts
            va, vb = TILT_MAX_DEG if va is None else va, TILT_MAX_DEG if vb is None else vb
        if key == "arm":  # ... and ran on the Jaco
            va, vb = va or "jaco", vb or "jaco"
        if va != vb:
            raise ConfigError(f"{names[0]} and {names[1]} differ in {key} ({va!r} against {vb!r}): their episodes are "
                              "not the same")


def _by_episode(data: dict) -> dict:
    out = {}
    for e in data["episodes"]:
        seed = e.get("episode_seed", e.get("seed"))
        out[(e["method"], e["scenario"], seed)] = e
    return out


def compare(a_dir, b_dir, methods_a=None, methods_b=None) -> dict:
    """The paired statistics of every (method of A, method of B) pair, per scenario and over all scenarios."""
    from hvs_sim.bench.stats import episode_success, mcnemar, rate, wilcoxon

    a, b = load_results(a_dir), load_results(b_dir)
    names = (str(a_dir), str(b_dir))
    _check_same(a, b, names)
    ea, eb = _by_episode(a), _by_episode(b)
    ma = list(methods_a or a["config"]["trackers"])
    mb = list(methods_b or b["config"]["trackers"])
    for ms, cfg, name in ((ma, a, names[0]), (mb, b, names[1])):
        unknown = [m for m in ms if m not in cfg["config"]["trackers"]]
        if unknown:
            raise ConfigError(f"{name} has no results for {unknown}; it holds {cfg['config']['trackers']}")
    success_px = a["config"].get("success_px", 1.0)
    rows = []
    for m1 in ma:
        for m2 in mb:
            if m1 == m2 and Path(a_dir).resolve() == Path(b_dir).resolve():
                continue
            for scen in [*a["config"]["scenarios"], "all"]:
                keys = sorted(k[1:] for k in ea if k[0] == m1 and (scen == "all" or k[1] == scen)
                              and (m2, *k[1:]) in eb)
                if not keys:
                    continue
                pa = [ea[(m1, *k)] for k in keys]
                pb = [eb[(m2, *k)] for k in keys]
                sa = [episode_success(e, success_px)["hvs_sim"] for e in pa]
                sb = [episode_success(e, success_px)["hvs_sim"] for e in pb]
                rows.append({
                    "a": m1, "b": m2, "scenario": scen, "episodes": len(keys),
                    "success_a": rate(sa), "success_b": rate(sb), "mcnemar": mcnemar(sa, sb),
                    "pose_error_mm": wilcoxon([e["final_pose_error_mm"] for e in pa],
                                              [e["final_pose_error_mm"] for e in pb]),
                    "image_error_px": wilcoxon([e["final_error_px"] for e in pa], [e["final_error_px"] for e in pb]),
                    "paired_pose_error_mm": [[e1["final_pose_error_mm"], e2["final_pose_error_mm"]]
                                             for e1, e2 in zip(pa, pb, strict=True)],
                })
    if not rows:
        raise ConfigError(f"{names[0]} and {names[1]} share no episodes of the methods asked for")
    return {"a": names[0], "b": names[1], "suite": a.get("suite"), "commits": [a.get("commit"), b.get("commit")],
            "test_note": "McNemar: exact binomial test on the discordant episodes (hvs_sim success rule); Wilcoxon: "
                         "signed-rank test on the paired final errors (a − b), two-sided",
            "rows": rows}


def compare_table(result: dict) -> str:
    def pct(r):
        return f"{100 * r['rate']:.0f} %"

    lines = [f"# {result['a']} (A) against {result['b']} (B), suite {result['suite']}", "", result["test_note"], "",
             ("| A | B | scenario | episodes | success A | success B | only A / only B | McNemar p | median Δ pose "
             "error (mm) | Wilcoxon p | median Δ image error (px) | Wilcoxon p |"),
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        mc, pe, ie = r["mcnemar"], r["pose_error_mm"], r["image_error_px"]
        lines.append(f"| {r['a']} | {r['b']} | {r['scenario']} | {r['episodes']} | {pct(r['success_a'])} | "
                     f"{pct(r['success_b'])} | {mc['only_a']} / {mc['only_b']} | {mc['p_value']:.3g} | "
                     f"{pe['median_difference']:+.2f} | {pe['p_value']:.3g} | {ie['median_difference']:+.3f} | "
                     f"{ie['p_value']:.3g} |")
    return "\n".join(lines) + "\n"


def compare_figure(result: dict, path: Path) -> Path:
    """Final pose error of A against B, episode by episode, one panel per pair over all scenarios (log axes)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hvs_sim.viz.figures import method_colour

    rows = [r for r in result["rows"] if r["scenario"] == "all"]
    fig, axes = plt.subplots(1, len(rows), figsize=(max(6.5, 4.5 * len(rows)), 4.6), squeeze=False)
    for ax, r in zip(axes[0], rows, strict=True):
        p = np.maximum(np.asarray(r["paired_pose_error_mm"], float), 1e-2)
        ax.scatter(p[:, 0], p[:, 1], s=14, color=method_colour(r["a"]), label=f"{r['episodes']} episodes")
        lo, hi = float(p.min()) * 0.8, float(p.max()) * 1.25
        ax.plot([lo, hi], [lo, hi], color="0.5", lw=0.8)
        ax.set(xscale="log", yscale="log", xlabel=f"A: {r['a']} (mm)", ylabel=f"B: {r['b']} (mm)",
               title=f"McNemar p {r['mcnemar']['p_value']:.2g}, Wilcoxon p {r['pose_error_mm']['p_value']:.2g}")
        ax.legend(loc="upper left", fontsize=8)
    fig.suptitle("final pose error, episode by episode (below the diagonal: A ends closer)", fontsize=10)
    fig.tight_layout()
    from hvs_sim.outputs import save_figure

    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
