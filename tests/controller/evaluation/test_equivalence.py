"""Welch's interval and the TOST, against scipy and closed forms; the difference
verdict on constructed samples."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy import stats

from controller.evaluation.equivalence import tost_p, welch
from controller.evaluation.verdicts import Verdict, difference_verdict, t_interval, value_verdict

#: The paper's UMC false positives in walking, participants 1-8.
WALKING_FP = [0.0, 0.0, 7.0, 0.0, 1.0, 0.0, 14.0, 0.0]

samples = st.lists(st.floats(-100, 100, allow_nan=False), min_size=2, max_size=40)


@given(samples, samples)
@settings(max_examples=80, deadline=None)
def test_welch_interval_is_scipys(v: list[float], p: list[float]) -> None:
    assume(np.var(v) > 1e-6 and np.var(p) > 1e-6)
    d = welch(v, p)
    ref = stats.ttest_ind(v, p, equal_var=False)
    ci = ref.confidence_interval(0.95)
    assert d.diff == pytest.approx(np.mean(v) - np.mean(p), abs=1e-9)
    assert d.df == pytest.approx(float(ref.df), rel=1e-9)
    assert (d.low, d.high) == (pytest.approx(float(ci.low), abs=1e-7),
                               pytest.approx(float(ci.high), abs=1e-7))


def test_welch_by_hand_on_the_walking_false_positives() -> None:
    d = welch([0.7, 0.8, 0.75, 0.72, 0.78], WALKING_FP)
    sd_p = float(np.std(WALKING_FP, ddof=1))  # 5.148
    assert d.se_paper == pytest.approx(sd_p / math.sqrt(8))  # 1.82
    assert d.se_paper == pytest.approx(1.82, abs=0.005)
    # The paper's error dominates: df close to the paper's 7.
    assert 7.0 <= d.df < 7.01
    assert d.diff == pytest.approx(0.75 - 2.75)


def test_tost_against_the_cauchy_closed_form() -> None:
    # Virtual [0, 2]: mean 1, s^2 = 2, se^2 = 1; the paper without spread: df = 1, where
    # the t distribution is Cauchy, F(x) = 1/2 + atan(x)/pi.
    d = welch([0.0, 2.0], [0.0, 0.0, 0.0], margin=2.0)
    assert (d.diff, d.se, d.df) == (1.0, 1.0, 1.0)
    p_low = 0.5 - math.atan((1.0 + 2.0) / 1.0) / math.pi  # P(T > 3)
    p_high = 0.5 + math.atan((1.0 - 2.0) / 1.0) / math.pi  # P(T < -1) = 0.25
    assert d.tost_p == pytest.approx(max(p_low, p_high)) and d.tost_p == pytest.approx(0.25)


def test_tost_against_the_two_degree_closed_form() -> None:
    # df = 2: F(x) = 1/2 + x / (2 sqrt(2 + x^2)).
    def cdf(x: float) -> float:
        return 0.5 + x / (2.0 * math.sqrt(2.0 + x * x))

    diff, se, margin = 0.4, 0.5, 1.5
    expected = max(1.0 - cdf((diff + margin) / se), cdf((diff - margin) / se))
    assert tost_p(diff, se, 2.0, margin) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(cdf(-2.2))


@given(samples, samples, st.floats(0.01, 50))
@settings(max_examples=60, deadline=None)
def test_tost_is_the_90_percent_interval_inside_the_margin(v: list[float], p: list[float],
                                                           margin: float) -> None:
    assume(np.var(v) > 1e-6 or np.var(p) > 1e-6)
    d = welch(v, p, margin)
    lo, hi = d.interval(0.90)
    assume(min(abs(lo + margin), abs(hi - margin)) > 1e-6)  # not on the boundary
    assert d.equivalent == (-margin < lo and hi < margin)


def test_no_spread_on_either_side_is_an_exact_difference() -> None:
    d = welch([10.0] * 5, [10.0, 10.0, 10.0], margin=1.0)
    assert (d.diff, d.se, d.low, d.high, d.tost_p) == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert difference_verdict(d) is Verdict.EQUIVALENT
    far = welch([7.0] * 5, [10.0, 10.0, 10.0], margin=1.0)
    assert far.tost_p == 1.0 and difference_verdict(far) is Verdict.DIFFERS


def test_too_few_values_or_a_negative_margin_are_refused() -> None:
    with pytest.raises(ValueError, match="two finite values"):
        welch([1.0, math.nan], [1.0, 2.0])
    with pytest.raises(ValueError, match="margin"):
        welch([1.0, 2.0], [1.0, 2.0], margin=-1.0)


def test_walking_false_positives_are_judged_with_both_errors() -> None:
    # A virtual mean of 0.75 with a small spread over seeds: the former rule calls it
    # "differs" (the paper's 2.75 is outside the narrow virtual interval), but the
    # paper's own mean has a standard error near 1.8.
    virtual = [0.7, 0.8, 0.75, 0.72, 0.78]
    assert value_verdict(2.75, t_interval(virtual)) is Verdict.DIFFERS
    d = welch(virtual, WALKING_FP, margin=1.0)
    assert d.low < 0.0 < d.high  # no difference shown
    assert d.high - d.low == pytest.approx(2 * stats.t.ppf(0.975, d.df) * d.se)
    assert difference_verdict(d) is Verdict.INCONCLUSIVE
    # The wider virtual interval of seeds 1-5 (mean 2.0) gets the same verdict.
    wide = welch([0.6, 1.2, 2.0, 2.8, 3.4], WALKING_FP, margin=1.0)
    assert difference_verdict(wide) is Verdict.INCONCLUSIVE
    # A difference the paper's spread cannot hide: stairs, 13.25 against about 3.
    stairs = [6.0, 16.0, 15.0, 1.0, 15.0, 19.0, 14.0, 20.0]
    assert difference_verdict(welch([3.0, 3.5, 2.5, 4.0, 3.2], stairs, 1.0)) \
        is Verdict.DIFFERS


def test_a_close_virtual_mean_is_equivalent() -> None:
    paper = [7.0, 10.0, 8.0, 10.0, 10.0, 10.0, 10.0, 10.0]  # UMC squats recognised
    near = welch([9.3, 9.4, 9.5, 9.35, 9.45], paper, margin=1.0)
    assert near.se_paper == pytest.approx(0.42, abs=0.01)
    assert difference_verdict(near) is Verdict.EQUIVALENT  # 90 %: [-0.77, 0.82]
    low = welch([8.0, 8.2, 8.1, 8.3, 8.15], paper, margin=1.0)
    assert low.low < -1.0 < low.high  # -1.2 [-2.2, -0.2]: reaches both sides of -1
    assert difference_verdict(low) is Verdict.INCONCLUSIVE
    tight = [10.0, 10.0, 10.0, 9.0, 10.0, 10.0, 10.0, 10.0, 9.0, 10.0, 10.0, 10.0]
    eq = welch([9.8, 9.9, 9.85, 9.75, 9.8], tight, margin=1.0)
    assert difference_verdict(eq) is Verdict.EQUIVALENT


def _sample(mean: float, sd: float, n: int) -> np.ndarray:
    """n values with exactly this mean and sample SD."""
    z = np.linspace(-1.0, 1.0, n)
    z = (z - z.mean()) / z.std(ddof=1)
    return mean + sd * z


@given(paper=st.lists(st.integers(0, 20), min_size=3, max_size=12),
       offset=st.floats(-5, 5), sd_v=st.floats(0.0, 5.0), n=st.integers(2, 10),
       more=st.integers(1, 60), margin=st.sampled_from([0.125, 1.0, 2.0]))
@settings(max_examples=200, deadline=None)
def test_more_seeds_cannot_turn_equivalent_into_differs(paper: list[int], offset: float,
                                                        sd_v: float, n: int, more: int,
                                                        margin: float) -> None:
    p = np.asarray(paper, dtype=np.float64)
    assume(p.std(ddof=1) > 0)
    se_p = p.std(ddof=1) / math.sqrt(p.size)
    assume(sd_v / math.sqrt(n) <= se_p)  # the paper's error dominates
    mean_v = float(p.mean()) + offset
    before = difference_verdict(welch(_sample(mean_v, sd_v, n), p, margin))
    after_d = welch(_sample(mean_v, sd_v, n + more), p, margin)
    assert after_d.diff == pytest.approx(mean_v - p.mean(), abs=1e-9)
    assert after_d.se_virtual <= sd_v / math.sqrt(n) + 1e-12
    if before is Verdict.EQUIVALENT:
        assert difference_verdict(after_d) is not Verdict.DIFFERS
