"""A wearer's learning curves: per-session points with their intervals, and the trend."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from controller.evaluation.learning_curve import (
    METRICS,
    SessionUse,
    learning_curves,
    mean_interval,
    point,
    poisson_rate,
    session_use,
    trend,
    wilson,
)
from tests.controller.evaluation.tick_builder import gait_recording, lifting_recording

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@given(value=finite, n=st.integers(min_value=3, max_value=40))
def test_a_constant_series_has_slope_zero_and_its_interval_holds_zero(value: float,
                                                                      n: int) -> None:
    tr = trend(range(1, n + 1), [value] * n)
    assert tr.n == n
    assert tr.slope == 0.0
    assert tr.low <= 0.0 <= tr.high


@given(a=st.floats(-100, 100), b=st.floats(-100, 100), n=st.integers(3, 30))
def test_a_straight_line_gives_its_slope(a: float, b: float, n: int) -> None:
    x = list(range(1, n + 1))
    tr = trend(x, [a + b * xi for xi in x])
    assert tr.slope == pytest.approx(b, abs=1e-7 * (1 + abs(a) + abs(b) * n))
    assert tr.intercept == pytest.approx(a, abs=1e-6 * (1 + abs(a) + abs(b) * n))
    assert tr.low <= tr.slope <= tr.high
    assert tr.high - tr.low == pytest.approx(0.0, abs=1e-6 * (1 + abs(a) + abs(b) * n))


@given(st.lists(finite, min_size=3, max_size=30), finite)
def test_shifting_every_value_leaves_the_slope(ys: list[float], shift: float) -> None:
    x = list(range(1, len(ys) + 1))
    a, b = trend(x, ys), trend(x, [y + shift for y in ys])
    scale = 1e-6 * (1 + max(abs(y) for y in ys) + abs(shift))
    assert b.slope == pytest.approx(a.slope, abs=scale)
    assert a.low <= a.slope <= a.high


def test_the_interval_is_the_textbook_one() -> None:
    # y = 1, 3, 2, 5, 4 on x = 1..5: slope 0.8, residual SS 3.6, SE sqrt(1.2/10),
    # t(0.975, 3) = 3.182446.
    tr = trend([1, 2, 3, 4, 5], [1, 3, 2, 5, 4])
    assert tr.slope == pytest.approx(0.8)
    half = 3.182446305 * math.sqrt(3.6 / 3 / 10)
    assert (tr.low, tr.high) == pytest.approx((0.8 - half, 0.8 + half), rel=1e-8)


def test_sessions_without_a_value_are_left_out_and_few_sessions_have_no_interval() -> None:
    tr = trend([1, 2, 3, 4], [2.0, math.nan, 4.0, math.nan])
    assert tr.n == 2 and tr.slope == pytest.approx(1.0)
    assert math.isnan(tr.low) and math.isnan(tr.high)
    assert trend([1], [5.0]).n == 1 and math.isnan(trend([1], [5.0]).slope)
    assert trend([], []).n == 0
    with pytest.raises(ValueError, match="differ in length"):
        trend([1, 2], [1.0])


@given(n=st.integers(1, 500), data=st.data())
def test_wilson_holds_the_proportion_inside_zero_one(n: int, data: st.DataObject) -> None:
    k = data.draw(st.integers(0, n))
    low, high = wilson(k, n)
    assert 0.0 <= low <= k / n <= high <= 1.0
    assert low < high


def test_wilson_known_value() -> None:
    # 8 of 10: the Wilson 95 % interval is 0.4902..0.9433.
    low, high = wilson(8, 10)
    assert (low, high) == pytest.approx((0.49016, 0.94331), abs=1e-4)
    assert all(math.isnan(v) for v in wilson(0, 0))


@given(k=st.integers(0, 1000), hours=st.floats(0.01, 100.0))
def test_poisson_interval_holds_the_rate(k: int, hours: float) -> None:
    low, high = poisson_rate(k, hours)
    assert 0.0 <= low <= k / hours < high
    assert (low == 0.0) == (k == 0)


def test_poisson_known_value() -> None:
    # Exact 95 % limits of a count of 2: 0.2422 and 7.2247 (Garwood).
    assert poisson_rate(2, 1.0) == pytest.approx((0.24220, 7.22470), abs=1e-4)
    assert poisson_rate(2, 0.5) == pytest.approx((0.48440, 14.4494), abs=1e-3)
    assert all(math.isnan(v) for v in poisson_rate(3, 0.0))


def test_mean_interval() -> None:
    m, low, high = mean_interval([0.2, 0.4])
    assert m == pytest.approx(0.3)
    assert (low, high) == pytest.approx((0.3 - 12.7062047 * 0.1, 0.3 + 12.7062047 * 0.1))
    assert math.isnan(mean_interval([0.5])[1])


def test_session_use_counts_from_evaluated_lifts_and_gait() -> None:
    good = lifting_recording("P01", "umc", good=True)
    bad = lifting_recording("P01", "umc", good=False)
    walk = gait_recording("P01", "umc", locks=3, kind="walking")
    stairs = gait_recording("P01", "umc", locks=2, kind="stair_walking")
    use = session_use(0.5, [*good.lifts, *bad.lifts],
                      [*walk.false_positives, *stairs.false_positives],
                      unconfirmed=2, incomplete=1)
    assert use.lifts == 8 + 2 + 1 and use.confirmed == 8
    # good: 4 recognised, 4 correct; bad: lifts 0 and 2 recognised, lifts 0 and 3 correct.
    assert use.recognised == 6 and use.correct_locks == 6
    assert len(use.lock_times_s) == 6
    assert use.walking_fp == 3 and use.stairs_fp == 2
    assert use.walking_hours == pytest.approx(19.99 / 3600)
    assert point("lifts_per_hour", use, 1).value == pytest.approx(22.0)
    assert point("recognition_rate", use, 1).value == pytest.approx(0.75)
    assert point("fp_per_hour_walking", use, 1).value == pytest.approx(3 / (19.99 / 3600))
    pec = session_use(0.5, lifting_recording("P01", "pec", good=True, intent=False).lifts, [])
    assert pec.recognised is None
    assert math.isnan(point("recognition_rate", pec, 1).value)


def test_session_use_refuses_impossible_counts() -> None:
    with pytest.raises(ValueError, match="confirmed"):
        SessionUse(hours=1.0, lifts=1, confirmed=2)
    with pytest.raises(ValueError, match="hours"):
        SessionUse(hours=-1.0)


def test_learning_curves_number_sessions_in_order_and_follow_an_improvement() -> None:
    uses = [SessionUse(hours=1.0, lifts=20, confirmed=20, recognised=10 + 2 * i,
                       correct_locks=8 + 3 * i, lock_times_s=(0.5 - 0.05 * i, 0.6 - 0.05 * i),
                       walking_hours=0.5, walking_fp=6 - i, stairs_hours=0.0)
            for i in range(4)]
    curves = learning_curves(uses)
    assert tuple(curves) == METRICS
    lock = curves["lock_rate"]
    assert [p.session for p in lock.points] == [1, 2, 3, 4]
    assert [p.value for p in lock.points] == pytest.approx([0.4, 0.55, 0.7, 0.85])
    assert lock.trend.slope == pytest.approx(0.15)
    assert curves["recognition_rate"].trend.slope == pytest.approx(0.1)
    assert curves["time_to_lock_s"].trend.slope == pytest.approx(-0.05)
    assert curves["fp_per_hour_walking"].trend.slope == pytest.approx(-2.0)
    # No stairs in any session: no points, no trend, and JSON says null.
    stairs = curves["fp_per_hour_stairs"]
    assert stairs.trend.n == 0 and stairs.to_dict()["points"][0]["value"] is None
