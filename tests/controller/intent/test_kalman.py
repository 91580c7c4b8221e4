"""Tests of the hip velocity Kalman filter and the velocity trigger."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from controller.config import ControllerConfig
from controller.intent.kalman import HipVelocityFilter
from controller.kernel.tick import triggered

DT = 0.01
R = 1.05e-3**2


def _model(accel_std: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    F = np.array([[1.0, DT], [0.0, 1.0]])
    G = np.array([[DT**2 / 2], [DT]])
    return F, G @ G.T * accel_std**2, np.array([[1.0, 0.0]])


def _reference(z: np.ndarray, accel_std: float) -> np.ndarray:
    """Textbook matrix Kalman filter with the documented initialisation."""
    F, Q, H = _model(accel_std)
    x = np.array([z[0], 0.0])
    P = np.diag([R, 1.0])
    out = [0.0]
    for zk in z[1:]:
        x = F @ x
        P = F @ P @ F.T + Q
        S = H @ P @ H.T + R
        K = P @ H.T / S
        x = x + (K * (zk - H @ x)).ravel()
        P = (np.eye(2) - K @ H) @ P
        out.append(x[1])
    return np.array(out)


@pytest.mark.parametrize("accel_std", [10.0, 15.0, 20.0])
def test_gain_converges_to_the_riccati_steady_state(accel_std: float) -> None:
    F, Q, H = _model(accel_std)
    P = solve_discrete_are(F.T, H.T, Q, np.array([[R]]))  # predicted covariance
    K = (P @ H.T / (H @ P @ H.T + R)).ravel()
    f = HipVelocityFilter(accel_std=accel_std)
    for _ in range(3000):
        f.step(0.0, 0.0)
    assert f.gain == pytest.approx(tuple(K), rel=1e-8)


def test_ramp_velocity_is_tracked_without_bias() -> None:
    f = HipVelocityFilter()
    w_left, w_right = 1.7, -0.4
    for k in range(400):
        wl, wr = f.step(0.1 + w_left * k * DT, -0.2 + w_right * k * DT)
    assert wl == pytest.approx(w_left, abs=1e-6)
    assert wr == pytest.approx(w_right, abs=1e-6)


def test_equals_textbook_filter_on_noisy_signal() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(500) * DT
    zl = 0.5 * np.sin(2.0 * t) + rng.normal(0, 1.05e-3, t.size)
    zr = 0.3 * np.cos(3.0 * t) + rng.normal(0, 1.05e-3, t.size)
    f = HipVelocityFilter(accel_std=12.0)
    got = np.array([f.step(a, b) for a, b in zip(zl, zr, strict=True)])
    assert got[:, 0] == pytest.approx(_reference(zl, 12.0), rel=1e-9, abs=1e-9)
    assert got[:, 1] == pytest.approx(_reference(zr, 12.0), rel=1e-9, abs=1e-9)
    # And it is a useful estimate of the true velocity.
    err = got[100:, 0] - np.cos(2.0 * t[100:])
    assert np.sqrt(np.mean(err**2)) < 0.15


def test_nan_sample_predicts_only_and_reset_forgets() -> None:
    f = HipVelocityFilter()
    assert all(math.isnan(w) for w in f.step(math.nan, 0.0))
    assert not f.initialised
    for k in range(200):
        f.step(k * DT, k * DT)
    wl, _ = f.step(math.nan, 2.0)  # skipped as a measurement: velocity carried over
    assert wl == pytest.approx(1.0, abs=1e-6)
    assert f.angles[0] == pytest.approx(2.0, abs=1e-6)
    f.reset()
    assert f.step(5.0, 5.0) == (0.0, 0.0)


def test_rejects_bad_parameters() -> None:
    with pytest.raises(ValueError, match="accel_std"):
        HipVelocityFilter(accel_std=0.0)
    with pytest.raises(ValueError, match="meas_std"):
        HipVelocityFilter(meas_std=math.nan)


def test_velocity_trigger() -> None:
    """The trigger compiled into the tick; an infinite threshold is refused by the
    configuration (`velocity_threshold` has finite bounds)."""
    assert triggered(1.0, 1.0, 1.0)
    assert triggered(2.0, 1.5, 1.0)
    assert not triggered(0.99, 3.0, 1.0)
    assert not triggered(3.0, 0.99, 1.0)
    assert not triggered(math.nan, 3.0, 1.0)
    assert triggered(0.6, 0.5, 0.5)
    with pytest.raises(ValueError):
        ControllerConfig(velocity_threshold=math.inf)
