"""The servo benchmark's table.md: one section per scenario, a row per method, from `method_results`' figures.
Apart from bench/servo.py, which runs the episodes, so that each module holds one job."""

from __future__ import annotations

from hvs_sim.sensor import BLUR_MODES


def _fmt(v, spec: str) -> str:
    return "–" if v is None else format(v, spec)


def _pct_ci(r: dict | None) -> str:
    if r is None or r["rate"] is None:
        return "–"
    lo, hi = r["ci95"]
    return f"{100 * r['rate']:.0f} % ({100 * lo:.0f}–{100 * hi:.0f})"


def _med_ci(r: dict, spec: str) -> str:
    if r["median"] is None:
        return "–"
    return f"{format(r['median'], spec)} ({format(r['ci95'][0], spec)}–{format(r['ci95'][1], spec)})"


def camera_label(camera) -> str:
    """A preset's name, or a SensorModel's name with the way it makes motion blur when that is not the default."""
    if isinstance(camera, str):
        return camera
    return camera.name if camera.blur == BLUR_MODES[0] else f"{camera.name} ({camera.blur} blur)"


def _help(r: dict) -> str:
    """The near-goal template as a method had it: switched to in how many episodes, or why it had none."""
    if r.get("near_goal_switched") is not None:
        return f"near-goal template (switched in {r['near_goal_switched']} of {r['episodes']})"
    return f"none: {r['near_goal_off']}" if r.get("near_goal_off") else "none"


def _runaways(r: dict) -> str:
    n, aborted = r.get("runaways", 0), r.get("aborted", 0)
    return f"{n} ({aborted} aborted)" if aborted else str(n)


def _drift(r: dict) -> str:
    d = r.get("max_drift_while_hidden_mm")
    if not d or d["median"] is None:
        return "–"
    return f"{d['median']:.1f}, {r['worst_drift_while_hidden_mm']:.1f}"


def servo_table(summary: dict, config) -> str:
    """table.md of a run: `config` is its ServoBenchConfig (read by field, not imported: the table is its module's
    only job and bench/servo.py imports it)."""
    from hvs_sim.bench.stats import RULES

    suite = f"suite {config.suite}, " if config.suite else ""
    lines = [(f"# Servo benchmark ({suite}{len(config.episode_seeds)} episodes per method and scenario, arm "
             f"{config.arm}, camera {camera_label(config.camera)}, {config.width}×{config.height})"), "",
             ("Success rules, each with its 95 % Wilson interval (translation and rotation: the camera's full pose "
             "error to the reference pose at the episode's end):"), ""]
    lines += [f"- **{rule}**: {text}" for rule, text in RULES.items()]
    lines += [("- **reached**: the hvs_sim bounds held for hold_steps steps at some point (an episode may then drift "
              "out; only `hvs_sim` counts it as a success when it ends within them)"), "",
              ("- **runaways**: episodes whose camera ended more than 50 mm further from the goal than it started, or "
               "that the workspace envelope stopped (aborted); must read 0"),
              ("- **camera drift while hidden**: how far the camera moved while the target was ≥ 50 % hidden, median "
               "and worst episode; **held**: steps the safety rule held the arm, mean per episode"), "",
              "DOFs: the DOFs each method commands. Medians with bootstrap 95 % intervals.", ""]
    for s, per in summary["results"].items():
        lines += [f"## {s}", "",
                  ("| method | DOFs | hvs_sim | CNS | Felton | ViSP | reached | runaways | final pose error (mm) "
                  "| p95 (mm) | final pose error (°) | p95 (°) | final image error (px) | max error in occlusion (px) "
                  "| re-acquired | time to re-acquire (s) | tracker drift while hidden (px) "
                  "| camera drift while hidden (mm): median, worst | held (steps) | faults | steps/s "
                  "| the loop's help near the goal |"),
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for t, r in per.items():
            occ = _fmt(r["median_max_error_during_occlusion_px"], ".1f")
            lines.append(
                f"| {t} | {len(r['controlled_dofs'])} | " + " | ".join(_pct_ci(r["success"][k]) for k in RULES)
                + f" | {_pct_ci(r['reached'])} | {_runaways(r)} | {_med_ci(r['final_pose_error_mm'], '.1f')} | "
                f"{_fmt(r.get('p95_final_pose_error_mm'), '.1f')} | {_med_ci(r['final_pose_error_deg'], '.2f')} | "
                f"{_fmt(r.get('p95_final_pose_error_deg'), '.2f')} | {_med_ci(r['final_error_px'], '.2f')} | {occ} | "
                f"{_pct_ci(r['reacquired'])} | {_med_ci(r['seconds_to_reacquire'], '.2f')} | "
                f"{_med_ci(r['max_tracker_error_while_hidden_px'], '.1f')} | {_drift(r)} | "
                f"{r.get('mean_held_steps', 0):.0f} | {r['fault_steps']} in "
                f"{r['fault_episodes']} ep. | {r['steps_per_second']:.1f} | {_help(r)} |")
        lines.append("")
    notes = sorted({e["tracker_contract"] for e in summary["episodes"] if e.get("tracker_contract")})
    if notes:  # a method that kept another corner convention: its figures say nothing of its tracking
        lines += ["## Contract warnings", "", *[f"- {n}" for n in notes], ""]
    return "\n".join(lines)
