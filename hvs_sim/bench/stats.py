"""Statistics a benchmark table needs: the field's success rules, intervals, and paired tests between two methods.

Success rules (each judged on an episode's final state; translation and rotation are the camera's full pose error
to the reference pose, all six DOFs):
- `hvs_sim`: held to the end: over the episode's last `hold_steps` steps the image error stays under `converge_px`
  and the pose error in the controlled DOFs under its bound (10 mm / 1°), and the final image error is ≤ 1 px.
  `reached` (the rule before: the bounds held for `hold_steps` steps at some point) is reported beside it.
- `cns` (Chen et al., CNS): final translation < 10 % of the initial translation error and rotation < 10°.
- `felton` (Felton et al., Siame-se(3), AEVS, MLVS): translation < 1 cm and rotation < 1°, or both cut to ≤ 10 % of
  their initial values.
- `visp` (ViSP's real-robot PBVS examples): translation < 0.5 mm and rotation < 0.5°.
"""

from __future__ import annotations

import math

import numpy as np

RULES = {
    "hvs_sim": "held to the end: image error < converge_px and pose error in the controlled DOFs < 10 mm / 1° over "
               "the last hold_steps steps, final image error ≤ 1 px",
    "cns": "CNS: final translation < 10 % of the initial translation error, rotation < 10°",
    "felton": "Felton et al.: translation < 1 cm and rotation < 1°, or both ≤ 10 % of their initial values",
    "visp": "ViSP: translation < 0.5 mm and rotation < 0.5°",
}
CI_Z = 1.959963984540054  # the normal quantile of a two-sided 95 % interval
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 0  # intervals are seeded: the same episodes give the same interval


def episode_success(e: dict, success_px: float) -> dict[str, bool]:
    """Each rule's verdict on one episode summary (RunStats.summary keys)."""
    t, r = e["final_pose_error_mm"], e["final_pose_error_deg"]
    t0, r0 = e["initial_pose_error_mm"], e["initial_pose_error_deg"]
    return {
        "hvs_sim": bool(e["held_to_end"] and e["final_error_px"] <= success_px),
        "cns": bool(t < 0.1 * t0 and r < 10.0),
        "felton": bool((t < 10.0 and r < 1.0) or (t <= 0.1 * t0 and r <= 0.1 * r0)),
        "visp": bool(t < 0.5 and r < 0.5),
    }


def wilson(successes: int, n: int, z: float = CI_Z) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (holds at 0 % and 100 %, unlike the normal one)."""
    if n <= 0:
        return (0.0, 1.0)
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


def rate(flags) -> dict:
    """Success rate with its 95 % Wilson interval."""
    flags = [bool(f) for f in flags]
    k, n = sum(flags), len(flags)
    lo, hi = wilson(k, n)
    return {"rate": k / n if n else None, "successes": k, "n": n, "ci95": [lo, hi]}


def median_ci(values, resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED) -> dict:
    """Median with a seeded percentile-bootstrap 95 % interval (None without values)."""
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], float)
    if not len(v):
        return {"median": None, "ci95": None, "n": 0}
    rng = np.random.default_rng(seed)
    meds = np.median(v[rng.integers(0, len(v), (resamples, len(v)))], axis=1)
    return {"median": float(np.median(v)), "ci95": [float(np.percentile(meds, 2.5)), float(np.percentile(meds, 97.5))],
            "n": len(v)}


def mcnemar(a, b) -> dict:
    """Exact McNemar test on paired successes: the discordant pairs against a fair coin (two-sided)."""
    from scipy.stats import binomtest

    a, b = np.asarray(a, bool), np.asarray(b, bool)
    only_a, only_b = int(np.sum(a & ~b)), int(np.sum(~a & b))
    n = only_a + only_b
    p = 1.0 if n == 0 else float(binomtest(only_a, n, 0.5).pvalue)
    return {"only_a": only_a, "only_b": only_b, "both": int(np.sum(a & b)), "neither": int(np.sum(~a & ~b)),
            "p_value": p}


def wilcoxon(a, b) -> dict:
    """Wilcoxon signed-rank test on paired values (a − b), two-sided; p = 1 when every pair is equal."""
    from scipy.stats import wilcoxon as _wilcoxon

    d = np.asarray(a, float) - np.asarray(b, float)
    d = d[np.isfinite(d)]
    if not len(d) or np.all(d == 0):
        return {"pairs": len(d), "median_difference": 0.0 if len(d) else None, "p_value": 1.0}
    return {"pairs": len(d), "median_difference": float(np.median(d)),
            "p_value": float(_wilcoxon(d, zero_method="wilcox").pvalue)}
