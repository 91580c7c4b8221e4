"""Tests of the stillness calibration and the live stillness monitor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.intent.calibration import (
    IDENTITY,
    Calibration,
    CalibrationError,
    StillnessMonitor,
    calibrate,
)

START = np.array([0.05, 0.07])  # models' mean at s = 0


def _still(n: int = 300, seed: int = 0, std: float = 2e-3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.array([0.21, -0.04]) + rng.normal(0, std, size=(n, 2))


def test_rest_posture_maps_onto_model_start() -> None:
    a = _still()
    cal = calibrate(a, START)
    assert isinstance(cal, Calibration)
    assert cal.offset_left == pytest.approx(a[:, 0].mean() - 0.05, abs=1e-15)
    assert cal.offset_right == pytest.approx(a[:, 1].mean() - 0.07, abs=1e-15)
    ql, qr = cal.apply(a[:, 0].mean(), a[:, 1].mean())
    assert (ql, qr) == pytest.approx((0.05, 0.07), abs=1e-15)
    assert IDENTITY.apply(0.3, 0.4) == (0.3, 0.4)


def test_moving_wearer_is_rejected_with_the_measured_std() -> None:
    a = _still()
    a[:, 1] += np.linspace(0.0, 0.2, len(a))  # right hip flexing during calibration
    std_deg = math.degrees(a[:, 1].std())
    with pytest.raises(CalibrationError, match=f"right {std_deg:.2f} deg"):
        calibrate(a, START)
    # A looser limit accepts the same data.
    calibrate(a, START, max_std=math.radians(5.0))


def test_std_limit_is_on_either_hip() -> None:
    a = _still(std=math.radians(1.2))
    with pytest.raises(CalibrationError, match="not still"):
        calibrate(a, START)
    assert calibrate(_still(std=math.radians(0.8)), START).offset_left == pytest.approx(
        0.16, abs=0.01
    )


@pytest.mark.parametrize(("left_deg", "right_deg"), [(88.5, 93.6), (2.0, -61.0), (-60.5, 0.0)])
def test_still_but_not_standing_is_rejected(left_deg: float, right_deg: float) -> None:
    # Held still at the bottom of a squat: the stillness test passes, the offset does not.
    a = _still(std=math.radians(0.2)) - np.array([0.21, -0.04])
    a += START + np.radians([left_deg, right_deg])
    with pytest.raises(CalibrationError, match="not standing") as err:
        calibrate(a, START)
    assert f"{left_deg:.1f} deg" in str(err.value) and f"{right_deg:.1f} deg" in str(err.value)
    # Just within the bound on both sides is a standing posture.
    b = _still(std=math.radians(0.2)) - np.array([0.21, -0.04]) + START + np.radians([59.5, -59.5])
    cal = calibrate(b, START)
    assert (math.degrees(cal.offset_left), math.degrees(cal.offset_right)) == pytest.approx(
        (59.5, -59.5), abs=0.1)


@pytest.mark.parametrize(
    ("angles", "message"),
    [
        (np.zeros((50, 2)), "at least 100 samples"),
        (np.zeros((200, 3)), "shape"),
        (
            np.where(np.arange(400).reshape(200, 2) == 7, np.nan, 0.0),
            "NaN or inf in 1 of 200 samples",
        ),
    ],
)
def test_bad_periods_rejected(angles: np.ndarray, message: str) -> None:
    with pytest.raises(CalibrationError, match=message):
        calibrate(angles, START)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"max_std": math.nan}, "max_std must be a positive number"),
    ({"max_std": 0.0}, "max_std must be a positive number"),
    ({"min_samples": 0}, "min_samples must be at least 2"),
])
def test_limits_that_would_switch_a_check_off_are_refused(kwargs: dict[str, float],
                                                          message: str) -> None:
    # NaN compares false, so a NaN limit would have accepted any movement.
    sweep = np.linspace([0.0, 0.0], [1.5, 1.5], 300)
    with pytest.raises(CalibrationError, match=message):
        calibrate(sweep if "max_std" in kwargs else np.empty((0, 2)), START,
                  **kwargs)  # type: ignore[arg-type]


def test_monitor_reports_live_std_over_window() -> None:
    mon = StillnessMonitor(window=100)
    assert all(math.isnan(s) for s in mon.std())
    a = _still(n=250, seed=3)
    a[150:, 0] += np.linspace(0.0, 0.3, 100)  # left hip starts moving at sample 150
    for k, (ql, qr) in enumerate(a):
        mon.push(ql, qr)
        if k == 149:
            assert mon.is_still()
            np.testing.assert_allclose(mon.std(), a[50:150].std(axis=0), rtol=1e-12)
            np.testing.assert_array_equal(mon.samples(), a[50:150])
    np.testing.assert_allclose(mon.std(), a[150:].std(axis=0), rtol=1e-12)
    assert not mon.is_still()
    mon.reset()
    for ql, qr in a[:99]:
        mon.push(ql, qr)
    assert not mon.full and not mon.is_still()
    mon.push(math.nan, 0.0)
    assert mon.full and not mon.is_still()
