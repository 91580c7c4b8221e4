"""The MACCEPA 2.0 torque against the check figures in docs/hardware.md."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import brentq

from controller.lowlevel.actuator import (
    PAPER_ACTUATOR,
    MaccepaParams,
    at_hard_stop,
    maccepa_torque,
    max_deflection,
    spring_elongation_mm,
)

# (P %, deflection at the 22 mm limit in degrees, T(30 deg), T(60 deg) or None)
TABLE = [
    (0, 93.8, 1.79, 12.93),
    (10, 87.5, 3.33, 15.65),
    (25, 78.0, 5.63, 19.74),
    (50, 61.8, 9.48, 26.56),
]


@pytest.mark.parametrize(("p", "limit_deg", "t30", "t60"), TABLE)
def test_torques_match_the_hardware_table(
    p: float, limit_deg: float, t30: float, t60: float
) -> None:
    assert maccepa_torque(math.radians(30), p) == pytest.approx(t30, abs=0.01)
    assert maccepa_torque(math.radians(60), p) == pytest.approx(t60, abs=0.01)
    assert math.degrees(max_deflection(p)) == pytest.approx(limit_deg, abs=0.1)


def test_peak_without_precompression_is_at_90_degrees() -> None:
    a = np.radians(np.linspace(0, 90, 901))
    t = maccepa_torque(a, 0.0)
    assert t.max() == pytest.approx(27.75, abs=0.01)
    assert math.degrees(a[t.argmax()]) == pytest.approx(90.0, abs=0.2)


@pytest.mark.parametrize(("p", "peak"), [(10, 29.53), (25, 29.38), (50, 27.58)])
def test_peaks_near_the_compression_limit(p: float, peak: float) -> None:
    # The table's peaks were read on a grid just short of the limit; ours is exact.
    a = np.linspace(0, max_deflection(p), 5000)
    assert maccepa_torque(a, p).max() == pytest.approx(peak, abs=0.05)


def test_torque_is_bounded_by_full_force_times_largest_lever() -> None:
    for p in np.linspace(0, 100, 21):
        a = np.linspace(0, math.radians(150), 600)
        assert maccepa_torque(a, float(p)).max() <= 67.2 * 22 * 0.020 + 1e-9


def test_no_torque_at_or_below_zero_deflection() -> None:
    assert maccepa_torque(0.0, 50) == 0.0
    assert maccepa_torque(-0.3, 50) == 0.0


def test_atan2_matters_beyond_acos_b_over_c() -> None:
    # Past 70.5 degrees I = C cos(a) - B < 0: atan(H/I) would flip the branch.
    a = math.radians(80)
    assert spring_elongation_mm(a) > spring_elongation_mm(math.radians(70))


@given(st.floats(0.0, 100.0), st.floats(0.0, 2.5))
def test_torque_is_monotonic_in_precompression(p: float, a: float) -> None:
    # Only below the stiffer setting's hard stop: past it that side cannot deflect further.
    a = min(a, max_deflection(min(100.0, p + 5.0)))
    lo = maccepa_torque(a, p)
    hi = maccepa_torque(a, min(100.0, p + 5.0))
    assert hi >= lo - 1e-9


def test_hard_stop_and_clamping() -> None:
    lim = max_deflection(25)
    assert at_hard_stop(lim + 0.01, 25)
    assert not at_hard_stop(lim - 0.01, 25)
    assert maccepa_torque(lim + 0.3, 25) == pytest.approx(maccepa_torque(lim, 25))


@pytest.mark.parametrize("bad", [-1.0, 100.5, float("nan")])
def test_bad_precompression_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="precompression"):
        maccepa_torque(0.5, bad)


def test_nan_deflection_is_refused() -> None:
    with pytest.raises(ValueError, match="NaN"):
        maccepa_torque(np.array([0.1, np.nan]), 10)


@given(st.floats(0.0, 100.0), st.floats(-1.0, 2.6))
def test_scalar_torque_model_equals_the_vectorised_one(p: float, a: float) -> None:
    from controller.lowlevel.actuator import TorqueModel

    assert TorqueModel(p)(a) == pytest.approx(maccepa_torque(a, p), abs=1e-9)


# -- the per-tick path against the code it replaced ----------------------------------------


def _oracle_max_deflection(pct: float, p: MaccepaParams = PAPER_ACTUATOR) -> float:
    """`max_deflection` as it was: the root found afresh on every call."""
    room = p.max_compression_mm * (1.0 - pct / 100.0)
    if room <= 0.0:
        return 0.0
    return float(brentq(lambda a: float(spring_elongation_mm(a, p)) - room, 0.0,
                        math.radians(150.0), xtol=1e-10))


def _oracle_torque(alpha: float, pct: float, p: MaccepaParams = PAPER_ACTUATOR) -> float:
    """`maccepa_torque` of one deflection as it was: the array code on a 0-d array."""
    a = np.asarray(alpha, dtype=np.float64)
    a_c = np.clip(a, 0.0, _oracle_max_deflection(pct, p))
    B, C, R = p.lever_arm_mm, p.roller_distance_mm, p.disk_radius_mm
    i = C * np.cos(a_c) - B
    h = C * np.sin(a_c) - R
    e = np.sqrt(i * i + h * h - R * R)
    lam = np.pi / 2 - np.arctan(e / R) + np.arctan2(h, i)
    elong = e + R * lam - (C - B)
    force = p.stiffness_n_per_mm * (p.max_compression_mm * pct / 100.0 + elong)
    return float(np.where(a > 0.0, force * C * np.sin(lam - a_c) / 1000.0, 0.0))


_OTHER = MaccepaParams(lever_arm_mm=12.0, roller_distance_mm=28.0, disk_radius_mm=6.0,
                       stiffness_n_per_mm=40.0)


@given(st.floats(0.0, 100.0), st.floats(-0.5, 3.0), st.sampled_from([PAPER_ACTUATOR, _OTHER]))
def test_one_deflection_gives_the_bits_of_the_array_code(
    p: float, a: float, params: MaccepaParams
) -> None:
    assert max_deflection(p, params) == _oracle_max_deflection(p, params)
    want = _oracle_torque(a, p, params)
    assert maccepa_torque(a, p, params) == want
    assert maccepa_torque(np.float64(a), p, params) == want
    assert float(maccepa_torque(np.array([a]), p, params)[0]) == want


@pytest.mark.parametrize("p", [0.0, 25.0, 60.0, 100.0])
def test_one_deflection_gives_the_bits_of_the_array_code_at_and_past_the_limit(
    p: float
) -> None:
    top = _oracle_max_deflection(p)
    for a in (top, math.nextafter(top, 0.0), math.nextafter(top, 9.0), top + 1.0, math.inf,
              5e-324, 0.0, -0.0, -math.inf):
        assert maccepa_torque(a, p) == _oracle_torque(a, p), a
    with pytest.raises(ValueError, match="NaN"):
        maccepa_torque(math.nan, p)
