"""Muscle-activity statistics against closed forms (Student t with 2 degrees of freedom,
Friedman with perfectly ordered ranks), hand-worked Holm corrections, scipy's own
Friedman test, and invariances (scale, a condition equal to its baseline)."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from controller.evaluation.muscle_stats import (
    OutcomeRow,
    friedman,
    holm,
    mean_t_interval,
    reductions,
    repeated_measures,
)


def _rows(condition: str, values: list[float], channel: str = "erector_spinae_left"
          ) -> list[OutcomeRow]:
    return [OutcomeRow(f"P{i:02d}", condition, channel, v) for i, v in enumerate(values)]


def test_reduction_of_three_participants_matches_the_t_distribution_closed_form() -> None:
    rows = _rows("none", [10.0, 10.0, 10.0]) + _rows("umc", [8.0, 7.0, 9.0])
    (r,) = reductions(rows, "none")
    # Reductions 20, 30, 10 %: mean 20, SD 10, SE 10 / sqrt(3), t = 2 sqrt(3).
    assert (r.channel, r.condition, r.baseline, r.n) == ("erector_spinae_left", "umc",
                                                          "none", 3)
    assert r.mean_pct == pytest.approx(20.0)
    half = 4.302652729911275 * 10.0 / math.sqrt(3.0)  # t(0.975, 2)
    assert (r.ci_low, r.ci_high) == (pytest.approx(20.0 - half), pytest.approx(20.0 + half))
    # Student t with 2 df: two-sided p = 1 - |t| / sqrt(t^2 + 2) = 1 - sqrt(6 / 7).
    assert r.p_value == pytest.approx(1.0 - math.sqrt(6.0 / 7.0), rel=1e-9)
    assert r.p_holm == pytest.approx(r.p_value)  # a family of one
    assert "t-test" in r.test and "Holm over 1" in r.test


def test_holm_hand_worked() -> None:
    # Sorted 0.01, 0.03, 0.04 -> 3 * 0.01, 2 * 0.03, max(0.06, 1 * 0.04).
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])
    got = holm([0.02, math.nan, 0.01])
    assert got[0] == pytest.approx(0.02) and got[2] == pytest.approx(0.02)
    assert math.isnan(got[1])


def test_holm_runs_over_channels_and_conditions() -> None:
    rows = (_rows("none", [10.0, 12.0, 9.0, 11.0])
            + _rows("umc", [8.0, 9.0, 7.0, 8.0])
            + _rows("pec", [9.0, 12.5, 8.0, 10.0])
            + _rows("none", [5.0, 6.0, 7.0, 5.0], "gluteus_maximus_right")
            + _rows("umc", [4.0, 5.0, 6.5, 4.0], "gluteus_maximus_right"))
    got = reductions(rows, "none")
    assert [(r.channel, r.condition) for r in got] == [
        ("erector_spinae_left", "umc"), ("erector_spinae_left", "pec"),
        ("gluteus_maximus_right", "umc")]
    assert [r.p_holm for r in got] == pytest.approx(holm([r.p_value for r in got]))
    assert all(r.p_holm >= r.p_value for r in got)
    assert all("Holm over 3" in r.test for r in got)


def test_participants_without_a_usable_baseline_are_left_out() -> None:
    rows = (_rows("none", [10.0, 0.0, math.nan, 10.0, 10.0])
            + _rows("umc", [5.0, 1.0, 1.0, 6.0, 4.0]))
    (r,) = reductions(rows, "none")
    assert r.n == 3 and r.mean_pct == pytest.approx(50.0)


def test_bad_input_is_named() -> None:
    with pytest.raises(ValueError, match="baseline 'springs_free' has no outcome rows"):
        reductions(_rows("umc", [1.0, 2.0]), "springs_free")
    with pytest.raises(ValueError, match="duplicate outcome for participant 'P00'"):
        reductions(_rows("none", [1.0]) + _rows("none", [2.0]), "none")


def test_one_participant_gives_no_interval_and_json_has_no_nan() -> None:
    (r,) = reductions(_rows("none", [4.0]) + _rows("umc", [3.0]), "none")
    assert r.n == 1 and r.mean_pct == pytest.approx(25.0)
    assert math.isnan(r.ci_low) and math.isnan(r.p_value) and math.isnan(r.p_holm)
    d = r.to_dict()
    assert d["ci_low"] is None and d["mean_pct"] == pytest.approx(25.0)
    json.dumps(d, allow_nan=False)


def test_friedman_of_perfectly_ordered_ranks_is_closed_form() -> None:
    # Three participants rank three conditions the same way: R = 3, 6, 9,
    # Q = 12 / (3 * 3 * 4) * 126 - 36 = 6; chi2 with 2 df: p = exp(-Q / 2).
    rows = (_rows("none", [10.0, 11.0, 12.0]) + _rows("springs_free", [9.0, 10.0, 11.0])
            + _rows("umc", [7.0, 8.0, 6.0]))
    (rm,) = repeated_measures(rows)
    assert rm.conditions == ("none", "springs_free", "umc")
    assert (rm.n, rm.df) == (3, 2)
    assert rm.statistic == pytest.approx(6.0)
    assert rm.p_value == pytest.approx(math.exp(-3.0))
    assert "Friedman" in rm.test
    assert rm.to_dict()["conditions"] == ["none", "springs_free", "umc"]


def test_friedman_of_two_conditions_is_n_when_every_participant_agrees() -> None:
    # R = n, 2n: Q = 12 / (6 n) * 5 n^2 - 9 n = n (the sign test's chi-square).
    for n in (2, 5, 9):
        x = np.column_stack([np.arange(n, dtype=float), np.arange(n, dtype=float) + 1])
        q, p = friedman(x)
        assert q == pytest.approx(float(n))
        assert p == pytest.approx(float(stats.chi2.sf(n, 1)))


def test_repeated_measures_subset_and_too_few() -> None:
    rows = (_rows("none", [10.0, 11.0]) + _rows("umc", [7.0, 8.0])
            + _rows("pec", [7.0]))
    (rm,) = repeated_measures(rows, ["none", "umc"])
    assert rm.n == 2 and rm.statistic == pytest.approx(2.0)
    (rm,) = repeated_measures(rows)
    assert rm.n == 1 and math.isnan(rm.p_value) and rm.to_dict()["p_value"] is None
    (rm,) = repeated_measures(_rows("none", [3.0, 3.0]) + _rows("umc", [3.0, 3.0]))
    assert (rm.statistic, rm.p_value) == (0.0, 1.0)


@settings(max_examples=50, deadline=None)
@given(st.integers(3, 5).flatmap(lambda k: st.lists(
    st.lists(st.integers(0, 4), min_size=k, max_size=k), min_size=3, max_size=10)))
def test_friedman_equals_scipy(table: list[list[int]]) -> None:
    x = np.asarray(table, dtype=np.float64)
    q, p = friedman(x)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy divides by zero when all rows tie
        ref = stats.friedmanchisquare(*x.T)
    if not math.isfinite(float(ref.statistic)):  # scipy: every row all-tied
        assert (q, p) == (0.0, 1.0)
        return
    assert q == pytest.approx(float(ref.statistic), rel=1e-9, abs=1e-12)
    assert p == pytest.approx(float(ref.pvalue), rel=1e-9, abs=1e-12)


_values = st.lists(st.floats(0.05, 5.0), min_size=2, max_size=12)


@settings(max_examples=60, deadline=None)
@given(_values, st.floats(0.2, 1.5), st.floats(1e-3, 1e3))
def test_scaling_every_value_leaves_reductions_unchanged(
        base: list[float], ratio: float, scale: float) -> None:
    cond = [b * ratio * (1.0 + 0.1 * i % 3) for i, b in enumerate(base)]
    rows = _rows("none", base) + _rows("umc", cond)
    scaled = _rows("none", [b * scale for b in base]) + _rows("umc", [c * scale for c in cond])
    (a,), (b,) = reductions(rows, "none"), reductions(scaled, "none")
    for field in ("mean_pct", "ci_low", "ci_high", "p_value"):
        x, y = getattr(a, field), getattr(b, field)
        assert x == pytest.approx(y, rel=1e-7, abs=1e-7), field
    (ra,), (rb,) = repeated_measures(rows), repeated_measures(scaled)
    assert ra.statistic == pytest.approx(rb.statistic)


@settings(max_examples=40, deadline=None)
@given(_values)
def test_a_condition_equal_to_its_baseline_reduces_nothing(base: list[float]) -> None:
    (r,) = reductions(_rows("none", base) + _rows("same", base), "none")
    assert (r.mean_pct, r.ci_low, r.ci_high, r.p_value) == (0.0, 0.0, 0.0, 1.0)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-50.0, 50.0), min_size=2, max_size=15))
def test_the_test_rejects_exactly_when_the_interval_excludes_zero(x: list[float]) -> None:
    mean, lo, hi, p = mean_t_interval(x)
    if lo == hi:
        return
    assert lo <= mean <= hi
    excludes = lo > 0.0 or hi < 0.0
    if min(abs(lo), abs(hi)) > 1e-9 * max(1.0, abs(mean)):
        assert (p < 0.05) == excludes
