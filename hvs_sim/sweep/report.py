"""What a sweep's finished tasks say: results.csv (a row a task), and report.md with its figure, grouped by the
axes asked for."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from hvs_sim.bench.servo import SUCCESS_PX
from hvs_sim.errors import ConfigError
from hvs_sim.sweep.spec import SweepSpec, task_id
from hvs_sim.sweep.tasks import _task_state


def load_records(spec: SweepSpec, out, unreadable: list | None = None) -> list[dict]:
    """The finished tasks of `spec` in `out` (grid order); the ids of damaged records are appended to `unreadable`."""
    tasks_dir = Path(out) / "tasks"
    records = []
    for p in spec.tasks():
        f = tasks_dir / f"{task_id(spec.kind, p)}.json"
        state = _task_state(f)
        if state in ("ok", "error"):  # an unreadable record counts as not done (re-run sets it aside)
            records.append(json.loads(f.read_text()))
        elif state == "corrupt" and unreadable is not None:
            unreadable.append(f.stem)
    return records


def _flat_metrics(record: dict) -> dict:
    return {k: v for k, v in record.get("metrics", {}).items() if k != "errors"}


def write_table(spec: SweepSpec, out) -> Path:
    """results.csv: one row per finished task, its parameters then its metrics."""
    records = load_records(spec, out)
    params = list(dict.fromkeys(k for p in spec.tasks() for k in p))
    metrics = list(dict.fromkeys(k for r in records for k in _flat_metrics(r)))
    import io

    from hvs_sim.outputs import write_atomic

    path = Path(out) / "results.csv"
    with io.StringIO(newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "status", *params, *metrics, "task_seconds", "engine", "error"])
        for r in records:
            m = _flat_metrics(r)
            w.writerow([r["id"], r["status"], *(r["params"].get(k, "") for k in params),
                        *("" if m.get(k) is None else m[k] for k in metrics), r.get("task_seconds", ""),
                        r.get("engine", ""), r.get("error", "")])
        write_atomic(path, f.getvalue())
    return path


def report(out, by: list[str], figures: bool = True) -> str:
    """Summary grouped by parameters (`by`), as markdown (also written to report.md), and figures."""
    out = Path(out)
    spec_file = out / "spec.json"
    if not spec_file.exists():
        raise ConfigError(f"{out} holds no sweep (spec.json missing); run `hvs-sim sweep SPEC --out {out}` first")
    try:
        spec = SweepSpec(**json.loads(spec_file.read_text()))
    except (OSError, ValueError, TypeError) as exc:
        raise ConfigError(f"{spec_file} cannot be read ({type(exc).__name__}: {exc}); run the sweep's spec into {out} "
                          "again to rewrite it") from None
    unreadable: list[str] = []
    records = load_records(spec, out, unreadable)
    damaged = (f"{len(unreadable)} task record(s) unreadable or damaged, left out (re-run the sweep to run them "
               f"again): {', '.join(unreadable[:5])}" + (", …" if len(unreadable) > 5 else "")) if unreadable else ""
    if not records:
        raise ConfigError(f"{out}: no finished tasks yet" + (f"; {damaged}" if damaged else ""))
    keys = list(spec.tasks()[0])
    bad = [b for b in by if b not in keys]
    if bad or not by:
        raise ConfigError(f"--by {','.join(by) or '(nothing)'}: group by task parameters; accepted: {', '.join(keys)}")
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault(tuple(r["params"][b] for b in by), []).append(r)
    if spec.kind == "servo":
        head = ["tasks", "errors", "success", "median convergence (s)", "median final error (px)"]
    else:
        head = ["tasks", "errors", "≤ 2 px (pooled frames)", "median px", "p95 px"]
    lines = [f"| {' | '.join(by)} | {' | '.join(head)} |", "|" + "---|" * (len(by) + len(head))]
    stats = {}
    for g, rs in groups.items():
        ok = [r["metrics"] for r in rs if r["status"] == "ok"]
        if spec.kind == "servo":
            conv = [m["seconds_to_converge"] for m in ok if m["seconds_to_converge"] is not None]
            cells = [len(rs), len(rs) - len(ok), f"{100 * np.mean([m['success'] for m in ok]):.0f} %" if ok else "–",
                     f"{np.median(conv):.2f}" if conv else "–",
                     f"{np.median([m['final_error_px'] for m in ok]):.2f}" if ok else "–"]
            stats[g] = {"success": float(np.mean([m["success"] for m in ok])) if ok else 0.0, "convergence": conv,
                        "final": [m["final_error_px"] for m in ok]}
        else:
            err = np.concatenate([m["errors"] for m in ok]) if ok else np.zeros(0)
            cells = [len(rs), len(rs) - len(ok), f"{100 * np.mean(err <= 2):.1f} %" if err.size else "–",
                     f"{np.median(err):.2f}" if err.size else "–", f"{np.percentile(err, 95):.2f}" if err.size else "–"]
            stats[g] = {"errors": err}
        lines.append(f"| {' | '.join(map(str, g))} | {' | '.join(map(str, cells))} |")
    text = "\n".join(lines) + "\n" + (f"\n{damaged}\n" if damaged else "")
    from hvs_sim.outputs import write_atomic

    write_atomic(out / "report.md", text)
    if figures:
        _report_figures(spec.kind, stats, by, out)
    return text


def _cdf(ax, labels: list[str], samples: list, threshold: float, threshold_label: str, xlabel: str, ylabel: str) -> None:
    """One CDF per group on a log axis, with the threshold line."""
    for label, values in zip(labels, samples):
        xs = np.sort(values)
        ax.plot(np.maximum(xs, 1e-3), np.arange(1, len(xs) + 1) / max(len(xs), 1), label=label)
    ax.set_xscale("log")
    ax.axvline(threshold, ls="--", color="k", lw=0.8, label=threshold_label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)


def _report_figures(kind: str, stats: dict, by: list[str], out: Path) -> None:
    from hvs_sim.viz.figures import plt

    labels = [" / ".join(map(str, g)) for g in stats]
    if kind == "servo":
        fig, ax = plt.subplots(1, 3, figsize=(16, 4.2))
        ax[0].barh(labels, [100 * s["success"] for s in stats.values()], color="tab:green")
        ax[0].set_xlabel("success (%)")
        ax[0].set_xlim(0, 100)
        ax[1].boxplot([s["convergence"] or [np.nan] for s in stats.values()], vert=False, tick_labels=labels)
        ax[1].set_xlabel("time to converge (s)")
        _cdf(ax[2], labels, [s["final"] for s in stats.values()], SUCCESS_PX, f"success ≤ {SUCCESS_PX:g} px",
             "final error (px)", "fraction of episodes")
    else:
        fig, ax = plt.subplots(1, 2, figsize=(13, 4.2))
        ax[0].barh(labels, [100 * np.mean(s["errors"] <= 2) if s["errors"].size else 0 for s in stats.values()],
                   color="tab:blue")
        ax[0].set_xlabel("frames ≤ 2 px (%)")
        ax[0].set_xlim(0, 100)
        _cdf(ax[1], labels, [s["errors"] for s in stats.values()], 2.0, "2 px", "tracking error (px)",
             "fraction of frames")
    fig.suptitle(f"sweep grouped by {', '.join(by)}")
    fig.tight_layout()
    from hvs_sim.outputs import save_figure

    save_figure(fig, out / "report.png", dpi=90)
    plt.close(fig)
