"""`hvs-sim bench compare A B`: two servo results of the same suite, compared episode by episode.

Methods pair by name (a method in both runs is compared with itself; one method each: those two; `--methods MA MB`
pairs explicitly); the runs are labelled by their folder names. Each pair is compared on the episodes both ran (same scenario, same seed, hence the
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
        if (Path(folder) / "episodes").is_dir():  # bench/pool.RECORDS_DIR: a run killed before it could write one
            raise ConfigError(f"{folder} holds episode records but no summary.json (its run was killed): complete it "
                              f"with the same `bench servo` command and --resume --out {folder}")
        raise ConfigError(f"{folder} holds no summary.json: give a folder written by `hvs-sim bench servo`")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{path} cannot be read as JSON ({exc})") from None
    if isinstance(data, dict) and data.get("interrupted"):  # said first: such a summary has no schema yet
        raise ConfigError(f"{path} is an interrupted run's partial summary ({data.get('completed_jobs', '?')} of "
                          f"{data.get('total_jobs', '?')} episodes finished): complete it first with the same `bench servo` "
                          f"command and --resume --out {Path(folder)}")
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


def run_labels(a_dir, b_dir) -> tuple[str, str]:
    """The runs' names in tables and figures: their folder names (with the parent's when both are named alike)."""
    pa, pb = Path(a_dir).resolve(), Path(b_dir).resolve()
    if pa.name != pb.name:
        return pa.name, pb.name
    return f"{pa.parent.name}/{pa.name}", f"{pb.parent.name}/{pb.name}"


def method_pairs(ma: list[str], mb: list[str], a_name: str, b_name: str) -> list[tuple[str, str]]:
    """Each method of A with the method of B of the same name; one method each (and no name shared): those two.
    Anything else needs --methods MA MB, which pairs explicitly."""
    shared = [m for m in ma if m in mb]
    if shared:
        return [(m, m) for m in shared]
    if len(ma) == 1 and len(mb) == 1:
        return [(ma[0], mb[0])]
    raise ConfigError(f"{a_name} ({', '.join(ma)}) and {b_name} ({', '.join(mb)}) share no method name: name the "
                      "pair with --methods MA MB (MA of A, MB of B)")


def compare(a_dir, b_dir, methods_a=None, methods_b=None) -> dict:
    """The paired statistics of each pair of methods (by name, or methods_a × methods_b as given), per scenario, and
    over all scenarios when there are several."""
    from hvs_sim.bench.stats import episode_success, mcnemar, rate, wilcoxon

    a, b = load_results(a_dir), load_results(b_dir)
    names = (str(a_dir), str(b_dir))
    labels = run_labels(a_dir, b_dir)
    _check_same(a, b, names)
    ea, eb = _by_episode(a), _by_episode(b)
    ma = list(methods_a or a["config"]["trackers"])
    mb = list(methods_b or b["config"]["trackers"])
    for ms, cfg, name in ((ma, a, names[0]), (mb, b, names[1])):
        unknown = [m for m in ms if m not in cfg["config"]["trackers"]]
        if unknown:
            raise ConfigError(f"{name} has no results for {unknown}; it holds {cfg['config']['trackers']}")
    same_run = Path(a_dir).resolve() == Path(b_dir).resolve()
    if methods_a and methods_b:
        pairs = [(m1, m2) for m1 in ma for m2 in mb if not (same_run and m1 == m2)]
    elif same_run:
        raise ConfigError(f"{names[0]} is compared with itself: name two of its methods with --methods MA MB")
    else:
        pairs = method_pairs(ma, mb, names[0], names[1])
    success_px = a["config"].get("success_px", 1.0)
    rows = []
    for m1, m2 in pairs:
        scenarios = [s for s in a["config"]["scenarios"]
                     if any(k[0] == m1 and k[1] == s and (m2, *k[1:]) in eb for k in ea)]
        for scen in [*scenarios, *(["all"] if len(scenarios) > 1 else [])]:  # one scenario: "all" would repeat it
            keys = sorted(k[1:] for k in ea if k[0] == m1 and (scen == "all" or k[1] == scen) and (m2, *k[1:]) in eb)
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
                "median_pose_error_mm": [float(np.median([e["final_pose_error_mm"] for e in p])) for p in (pa, pb)],
                "median_image_error_px": [float(np.median([e["final_error_px"] for e in p])) for p in (pa, pb)],
                "paired_pose_error_mm": [[e1["final_pose_error_mm"], e2["final_pose_error_mm"]]
                                         for e1, e2 in zip(pa, pb, strict=True)],
            })
    if not rows:
        raise ConfigError(f"{names[0]} and {names[1]} share no episodes of the methods asked for")
    return {"a": names[0], "b": names[1], "label_a": labels[0], "label_b": labels[1], "suite": a.get("suite"),
            "commits": [a.get("commit"), b.get("commit")],
            "test_note": "McNemar: exact binomial test on the discordant episodes (hvs_sim success rule); Wilcoxon: "
                         "signed-rank test on the paired final errors (a − b), two-sided",
            "rows": rows}


def _pair_name(r: dict, result: dict) -> str:
    """A row's methods with their runs: one name when a method is compared with itself."""
    la, lb = result.get("label_a", "A"), result.get("label_b", "B")
    return f"{r['a']} ({la} / {lb})" if r["a"] == r["b"] else f"{r['a']} ({la}) / {r['b']} ({lb})"


def compare_table(result: dict) -> str:
    def pct(r):
        return f"{100 * r['rate']:.0f} %"

    la, lb = result.get("label_a", "A"), result.get("label_b", "B")
    lines = [f"# {la} (A: {result['a']}) against {lb} (B: {result['b']}), suite {result['suite']}", "",
             result["test_note"], "",
             (f"| method A ({la}) | method B ({lb}) | scenario | episodes | success A | success B | only A / only B | "
              "McNemar p | median Δ pose error (mm) | Wilcoxon p | median Δ image error (px) | Wilcoxon p |"),
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        mc, pe, ie = r["mcnemar"], r["pose_error_mm"], r["image_error_px"]
        lines.append(f"| {r['a']} | {r['b']} | {r['scenario']} | {r['episodes']} | {pct(r['success_a'])} | "
                     f"{pct(r['success_b'])} | {mc['only_a']} / {mc['only_b']} | {mc['p_value']:.3g} | "
                     f"{pe['median_difference']:+.2f} | {pe['p_value']:.3g} | {ie['median_difference']:+.3f} | "
                     f"{ie['p_value']:.3g} |")
    return "\n".join(lines) + "\n"


FIGURE_WIDTH_IN, FIGURE_DPI = 13.0, 110  # 1430 px: readable on a screen and in a page (at most 1600 px)
ROW_HEIGHT_IN, FIGURE_BASE_IN = 0.42, 1.6
MIN_ERROR = 1e-3  # log axes: a zero error is drawn here


def compare_figure(result: dict, path: Path) -> Path:
    """One panel per measure (success rate, final pose error, final image error), one row per pair of methods (over
    all scenarios, or the one there is): A and B side by side on each row, p-values beside."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    per_pair = {}
    for r in result["rows"]:  # the "all" row where there is one, else the single scenario's
        key = (r["a"], r["b"])
        if key not in per_pair or r["scenario"] == "all":
            per_pair[key] = r
    rows = list(per_pair.values())
    la, lb = result.get("label_a", "A"), result.get("label_b", "B")
    measures = (("success, hvs_sim rule (%; p: McNemar)",
                 lambda r: [100 * r["success_a"]["rate"], 100 * r["success_b"]["rate"]], "mcnemar", False),
                ("median final pose error (mm; p: Wilcoxon)", lambda r: r["median_pose_error_mm"], "pose_error_mm", True),
                ("median final image error (px; p: Wilcoxon)", lambda r: r["median_image_error_px"], "image_error_px",
                 True))
    height = FIGURE_BASE_IN + ROW_HEIGHT_IN * len(rows)
    fig, axes = plt.subplots(1, len(measures), figsize=(FIGURE_WIDTH_IN, height), sharey=True, squeeze=False)
    y = np.arange(len(rows))
    for ax, (title, values, test, log) in zip(axes[0], measures, strict=True):
        v = np.array([values(r) for r in rows], float)
        if log:
            v = np.maximum(v, MIN_ERROR)
        ax.hlines(y, v.min(axis=1), v.max(axis=1), color="0.75", lw=2)
        ax.scatter(v[:, 0], y, s=36, color="tab:blue", label=f"A: {la}", zorder=3)
        ax.scatter(v[:, 1], y, s=36, color="tab:orange", marker="D", label=f"B: {lb}", zorder=3)
        for yi, r in zip(y, rows, strict=True):
            ax.annotate(f"p {r[test]['p_value']:.2g}", (1.0, yi), xycoords=("axes fraction", "data"), xytext=(4, 0),
                        textcoords="offset points", va="center", fontsize=8, color="0.3")
        if log:  # whole decades, labelled at the decades only (minor labels overlap on a short range)
            from matplotlib.ticker import NullFormatter

            lo, hi = np.floor(np.log10(v.min() * 0.8)), np.ceil(np.log10(v.max() * 1.25))
            ax.set_xscale("log")
            ax.set_xlim(10 ** lo, 10 ** max(hi, lo + 1))
            ax.xaxis.set_minor_formatter(NullFormatter())
        else:
            ax.set_xlim(-5, 105)
        ax.set_title(title, fontsize=10)
        ax.grid(axis="x", color="0.9")
    axes[0][0].set_yticks(y, [f"{_pair_name(r, result)}\n{r['scenario']}, {r['episodes']} episodes" for r in rows],
                          fontsize=8)
    axes[0][0].invert_yaxis()
    axes[0][0].legend(loc="lower left", fontsize=8, bbox_to_anchor=(0, 1.08), ncol=2, frameon=False)
    fig.suptitle(f"{la} (A) against {lb} (B), suite {result['suite']}: episode by episode on the same seeds",
                 fontsize=10)
    fig.tight_layout()
    from hvs_sim.outputs import save_figure

    save_figure(fig, path, dpi=FIGURE_DPI)
    plt.close(fig)
    return path
