"""The pose bound (control/bound.py), the camera's noise model it reads (camera_model.output_variance) and
`hvs-sim budget`."""

import json

import numpy as np
import pytest

from hvs_sim.camera_model import SensorState, jpeg_variance, output_variance, sensor_preset
from hvs_sim.cli import main
from hvs_sim.control.bound import pose_bound
from hvs_sim.control.dvs import luminance_interaction
from hvs_sim.errors import InputError


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
    assert main(["budget", "--camera", "ideal", "phone_handheld", "--target", "crescent", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| ideal | crescent | 0.15 | 0.8 |" in text and "| phone_handheld | crescent |" in text
    rows = json.loads((out / "budget.json").read_text())["rows"]
    ideal, phone = rows
    assert 0 < ideal["filtered_mm"] < phone["filtered_mm"]  # a clean render is the more exact
    assert phone["filtered_mm"] == pytest.approx(phone["one_frame_mm"] / np.sqrt(phone["filter_frames"]))
    assert (out / "budget.png").stat().st_size > 5_000
    assert main(["budget", "--target-width", "0.05", "--standoff", "1.4", "--out", str(tmp_path / "c")]) == 2
    assert "too small" in capsys.readouterr().err
