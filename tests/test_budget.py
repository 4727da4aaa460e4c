"""The pose bound (control/bound.py), the camera's noise model it reads (sensor.output_variance) and
`hvs-sim budget`."""

import json

import numpy as np
import pytest

from hvs_sim.cli import main
from hvs_sim.control.bound import pose_bound
from hvs_sim.control.laws.dvs import luminance_interaction
from hvs_sim.errors import ConfigError, InputError
from hvs_sim.sensor import SensorState, jpeg_variance, output_variance, sensor_preset


def test_a_ramp_bounds_sideways_translation_as_the_closed_form_says():
    """I = a·x over N pixels at depth Z, noise σ²: var(vx) ≥ Z² σ² / (N a²)."""
    rng = np.random.default_rng(0)
    n, a, Z, var = 500, 80.0, 0.8, 4.0
    x, y = rng.uniform(-0.1, 0.1, n), rng.uniform(-0.1, 0.1, n)
    b = pose_bound(np.full(n, a), np.zeros(n), x, y, Z, np.full(n, var), dofs=("vx",))
    assert b.cov[0, 0] == pytest.approx(Z ** 2 * var / (n * a ** 2), rel=1e-12)
    assert b.translation_mm == pytest.approx(1e3 * Z * np.sqrt(var / n) / a, rel=1e-12)
    assert b.scaled(4).translation_mm == pytest.approx(b.translation_mm / 2)
    with pytest.raises(InputError, match="no information"):  # a ramp says nothing of vy
        pose_bound(np.full(n, a), np.zeros(n), x, y, Z, np.full(n, var), dofs=("vx", "vy"))


def test_least_squares_on_noisy_pixels_reaches_the_bound_on_all_six_dofs():
    """The efficient estimator of the linearised model (least squares weighted by 1/σ²) has the bound's covariance."""
    rng = np.random.default_rng(1)
    n, Z = 400, 0.8
    x, y = rng.uniform(-0.08, 0.08, n), rng.uniform(-0.06, 0.06, n)
    gx, gy = rng.normal(0, 300, n), rng.normal(0, 300, n)
    var = rng.uniform(1, 9, n)
    b = pose_bound(gx, gy, x, y, Z, var)
    L = luminance_interaction(gx, gy, x, y, Z)
    W = 1 / var
    est = np.linalg.solve((L * W[:, None]).T @ L, (L * W[:, None]).T @ (rng.normal(0, 1, (n, 3000)) * np.sqrt(var)[:, None]))
    emp = np.cov(est)
    assert np.allclose(np.diag(emp) / np.diag(b.cov), 1, atol=0.08)
    assert b.pixels == n and set(b.per_dof()) == {"vx", "vy", "vz", "wx", "wy", "wz"}


def test_the_noise_model_matches_the_camera_model_s_own_frames():
    """Per-pixel variance of many still captures (no JPEG) against output_variance, over mid-tone pixels."""
    model = sensor_preset("phone_handheld", jpeg_quality=0)
    rng = np.random.default_rng(2)
    linear = rng.uniform(0.01, 0.15, (24, 32, 3)).astype(np.float32)
    state = SensorState(model, seed=3, shape=(24, 32))
    state.gain = 1.5
    state._update_gain = lambda *a: None  # hold the gain: the variance of one exposure level is what is modelled
    frames = np.stack([state.capture(linear, k, 0.0, 1 / 30) for k in range(400)]).astype(np.float64)
    predicted = output_variance(model, linear, 1.5)
    ratio = frames.var(axis=0).ravel() / predicted.ravel()
    assert 0.9 < np.median(ratio) < 1.1
    assert np.isinf(output_variance(model, np.full((2, 2, 3), 0.9, np.float32), 1.5)).all()  # saturated
    flat = np.full((32, 32, 3), 128, np.uint8)
    assert jpeg_variance(flat, 0) == 0.0


def test_budget_prints_the_bound_for_a_built_in_target(tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["budget", "--camera", "ideal", "phone_handheld", "--target", "crescent", "--bound-only",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| ideal | crescent | 0.15 | 0.8 |" in text and "| phone_handheld | crescent |" in text
    rows = json.loads((out / "budget.json").read_text())["rows"]
    ideal, phone = rows
    assert 0 < ideal["filtered_mm"] < phone["filtered_mm"]  # a clean render is the more exact
    assert phone["filtered_mm"] == pytest.approx(phone["one_frame_mm"] / np.sqrt(phone["filter_frames"]))
    assert (out / "budget.png").stat().st_size > 5_000
    assert main(["budget", "--target-width", "0.05", "--standoff", "1.4", "--out", str(tmp_path / "c")]) == 2
    assert "too small" in capsys.readouterr().err
    assert main(["budget", "--bound-only", "--episodes", "2", "--out", str(tmp_path / "d")]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["budget", "--episodes", "-1", "--out", str(tmp_path / "e")]) == 2
    assert not (tmp_path / "d").exists() and not (tmp_path / "e").exists()
    # a folder of earlier results is refused before any measuring, not after
    assert main(["budget", "--bound-only", "--out", str(out)]) == 2 and "not empty" in capsys.readouterr().err


def test_the_prediction_is_where_the_loop_stops_given_the_tracker_s_gain_and_errors():
    """A bias alone is the answer's length; a gain G moves the stop to −(I + G)⁻¹ e; noise averages over the frames."""
    from hvs_sim.bench.budget import Measured, predict

    def m(bias, gain=((0.0, 0.0), (0.0, 0.0)), noise=(0.0, 0.0), near=(0.0, 0.0), offset=(0.0, 0.0)):
        return Measured((180.0, 180.0), bias, noise, gain, offset, near, 90, 24)

    assert predict(m((3.0, 4.0)), 19) == pytest.approx(5.0)
    # the tracker sees only half of the camera's motion along the first direction: the loop stops twice as far
    assert predict(m((3.0, 0.0), gain=((-0.5, 0.0), (0.0, 0.0))), 19) == pytest.approx(6.0)
    # zero bias, unit Gaussian spread per direction: the median length of a 2-D standard normal, √(2 ln 2)
    assert predict(m((0.0, 0.0), noise=(4.0, 4.0)), 16) == pytest.approx(np.sqrt(2 * np.log(2)), rel=0.02)
    assert predict(m((0.0, 0.0), noise=(4.0, 4.0)), 64) < predict(m((0.0, 0.0), noise=(4.0, 4.0)), 16)
    assert predict(m((1.0, 0.0), gain=((-1.0, 0.0), (0.0, 0.0))), 19) is None  # it does not see the offset at all
    assert predict(m((1.0, 0.0), gain=((-1.5, 0.0), (0.0, 0.0))), 19) is None  # it sees it backwards: no stable stop
    assert predict(m((1.0, 0.0), gain=((-0.999, 0.0), (0.0, 0.0))), 19) is None  # 1000× an error is no answer
    assert predict(m((1.0, 0.0), offset=(2.0, 0.0)), 19) == pytest.approx(3.0)  # the near-goal fit's constant adds


def test_budget_measures_the_tracker_and_runs_the_loop_on_a_clean_camera(tmp_path, capsys):
    """Through `ideal` the tracker held at the goal has no bias and no noise; around it, its error is what the
    render leaves (small, not zero); one closed-loop episode ends near the goal; the table shows both."""
    from hvs_sim.bench import budget as b

    scen = b.budget_scenario("ideal", 0.8)
    with pytest.raises(ConfigError, match="near_poses"):
        b.measure(scen, hold_frames=4, near_poses=3)  # three unknowns a direction: nothing left to measure the rest
    m = b.measure(scen, hold_frames=4, near_poses=8)
    assert max(map(abs, m.bias_mm)) < 0.1 and max(m.noise_mm) < 0.05  # the same frame each time
    assert 0 < max(m.near_mm) < 5 and all(180 < v < 185 for v in m.mm_per_px) and m.unaligned == 0
    out = tmp_path / "b"
    assert main(["budget", "--camera", "ideal", "--episodes", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "What the loop reaches" in text and "| ideal | star_field | 0.15 |" in text
    data = json.loads((out / "budget.json").read_text())
    assert data["arm"] == "jaco" and data["episodes"] == 1
    row = data["rows"][0]
    assert len(row["closed_loop"]) == 1 and row["closed_loop"][0]["seed"] == b.EPISODE_SEED0
    assert 0 < row["closed_loop_median_mm"] < 10  # converged: the benchmark's bound
    assert 0 < row["predicted_median_mm"] < 10 and row["measured"]["hold_frames"] == b.HOLD_FRAMES


def test_budget_bounds_the_near_goal_template_and_refuses_one_that_runs_off_the_image(tmp_path, capsys):
    """`--near-goal-inset`: the bound on the grown template the loop tracks at the goal, far tighter than on the
    default one (its pixels pin the weak directions); a growth that leaves the image is a clear error."""
    out = tmp_path / "b"
    assert main(["budget", "--camera", "robot_cell", "--bound-only", "--near-goal-inset", "off", "--out",
                 str(tmp_path / "a")]) == 0
    small = json.loads((tmp_path / "a" / "budget.json").read_text())["rows"][0]
    assert main(["budget", "--camera", "robot_cell", "--bound-only", "--near-goal-inset", "-90", "--out", str(out)]) == 0
    assert "288×252 (-90)" in capsys.readouterr().out
    data = json.loads((out / "budget.json").read_text())
    grown = data["rows"][0]
    assert data["near_goal_inset_px"] == -90 and grown["template_inset_px"] == -90 and small["template_inset_px"] == 8
    # the default: the loop's automatic near-goal template, a quarter of the image
    assert main(["budget", "--camera", "robot_cell", "--bound-only", "--out", str(tmp_path / "e")]) == 0
    auto = json.loads((tmp_path / "e" / "budget.json").read_text())
    assert auto["near_goal_inset_px"] == "auto" and auto["rows"][0]["template_inset_px"] < -80
    assert auto["rows"][0]["template_px"][0] * auto["rows"][0]["template_px"][1] <= 0.25 * 640 * 480
    # a target that fills a quarter of the image already: the default template, and why
    assert main(["budget", "--camera", "robot_cell", "--bound-only", "--standoff", "0.4", "--target-width", "0.3",
                 "--out", str(tmp_path / "f")]) == 0
    row = json.loads((tmp_path / "f" / "budget.json").read_text())["rows"][0]
    assert row["template_inset_px"] == 8 and "already holds" in row["near_goal_off"]
    assert grown["template_px"][0] == small["template_px"][0] + 196  # 8 px inside the outline → 90 px beyond it
    assert grown["pixels"] > 10 * small["pixels"]
    assert 0 < grown["filtered_mm"] < 0.2 * small["filtered_mm"]
    assert main(["budget", "--bound-only", "--near-goal-inset", "-300", "--out", str(tmp_path / "c")]) == 2
    assert "runs off the 640×480 image" in capsys.readouterr().err
    assert main(["budget", "--bound-only", "--near-goal-inset", "5", "--out", str(tmp_path / "d")]) == 2
    assert "near_goal_inset_px" in capsys.readouterr().err
