"""Per-lift outcomes against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from controller.emg.outcomes import lift_outcome, normalised_cycle, window_outcome
from controller.emg.processing import EmgProcessing, condition, process

FS = 2000.0


def test_constant_envelope_outcomes() -> None:
    env = np.column_stack([np.full(3000, 0.4), np.full(3000, 0.1)])
    out = window_outcome(env, FS, (1000, 2001))
    assert out.peak == pytest.approx((0.4, 0.1))
    assert out.mean == pytest.approx((0.4, 0.1))
    assert out.iemg == pytest.approx((0.4 * 0.5, 0.1 * 0.5))  # 1000 intervals of 0.5 ms
    assert out.duration_s == pytest.approx(1001 / FS)


def test_ramp_cycle_is_linear_over_101_points() -> None:
    env = np.linspace(0.0, 1.0, 5001)[:, None] * np.array([1.0, 2.0])
    cycle = normalised_cycle(env, (1000, 3001))
    assert cycle.shape == (101, 2)
    expected = np.linspace(env[1000, 0], env[3000, 0], 101)
    np.testing.assert_allclose(cycle[:, 0], expected, atol=1e-12)
    np.testing.assert_allclose(cycle[:, 1], 2 * expected, atol=1e-12)


def test_iemg_of_the_envelope_equals_the_rectified_integral() -> None:
    a, f = 2e-4, 93.1
    t = np.arange(int(12 * FS)) / FS
    raw = (a * np.sin(2 * np.pi * f * t))[:, None]
    s = EmgProcessing(precision="float64")
    env = process(raw, FS, s)
    rect = np.abs(condition(raw, FS, s))
    window = (int(3 * FS), int(9 * FS))
    iemg = window_outcome(env, FS, window).iemg[0]
    assert iemg == pytest.approx(np.trapezoid(rect[slice(*window), 0], dx=1 / FS), rel=1e-3)
    assert iemg == pytest.approx(2 * a / np.pi * 6.0, rel=2e-3)


def test_lift_with_phases() -> None:
    env = np.zeros((1000, 1))
    env[200:400, 0] = 1.0
    out = lift_outcome(env, 100.0, (100, 600), {"lowering": (100, 300), "lifting": (300, 600)})
    assert out.lift.peak == (1.0,)
    assert out.phases["lowering"].mean == pytest.approx((0.5,))
    assert out.phases["lifting"].mean == pytest.approx((100 / 300,))
    assert out.cycle.shape == (101, 1)
    assert out.to_dict()["phases"]["lowering"]["peak"] == [1.0]
    with pytest.raises(ValueError, match="not inside the lift"):
        lift_outcome(env, 100.0, (100, 600), {"late": (500, 700)})


def test_bad_windows_are_refused() -> None:
    env = np.ones((100, 1))
    with pytest.raises(ValueError, match="window"):
        window_outcome(env, 100.0, (50, 50))
    with pytest.raises(ValueError, match="window"):
        window_outcome(env, 100.0, (90, 101))
    env[3, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        window_outcome(env, 100.0, (0, 10))
