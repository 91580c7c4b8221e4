"""Cohort statistics against independent oracles: scipy's own Wilcoxon test, hand-worked
rank-biserial values, the exact minimum p-values of the signed-rank test, and the
normal-theory width of a confidence interval."""

from __future__ import annotations

import math
import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from controller.evaluation.cohort_stats import (
    _signed_rank_sums,
    bootstrap_mean_ci,
    compare,
    power_curve,
    rank_biserial,
    wilcoxon_p,
)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.integers(-4, 4), min_size=6, max_size=6), min_size=1,
                max_size=8))
def test_vectorised_wilcoxon_equals_scipy_row_by_row(rows: list[list[int]]) -> None:
    d = np.asarray(rows, dtype=np.float64)
    got = wilcoxon_p(d)
    for row, p in zip(d, got, strict=True):
        if not np.any(row):
            assert p == 1.0
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ref = stats.wilcoxon(row, zero_method="wilcox", method="approx",
                                 correction=True).pvalue
        assert math.isclose(p, float(np.nan_to_num(ref, nan=1.0)), rel_tol=1e-9,
                            abs_tol=1e-12)


def test_rank_biserial_hand_worked() -> None:
    # |d| ranks 1, 2, 3: R+ = 1 + 3, R- = 2 -> (4 - 2) / 6.
    assert rank_biserial([1.0, -2.0, 3.0]) == 1 / 3
    assert rank_biserial([0.5, 2.0, 0.0]) == 1.0  # zeros dropped
    assert rank_biserial([-1.0, -1.0]) == -1.0
    # Ties: |d| = 1, 1, 2 -> ranks 1.5, 1.5, 3; R+ = 1.5 + 3, R- = 1.5.
    assert rank_biserial([1.0, -1.0, 2.0]) == (4.5 - 1.5) / 6
    assert math.isnan(rank_biserial([0.0, 0.0]))


def test_power_is_zero_without_a_difference_and_bounded_by_the_smallest_p() -> None:
    sizes = (4, 5, 6, 10, 40)
    assert power_curve(np.zeros(30), sizes) == (0.0,) * 5
    # Every difference positive: the test cannot reach p < 0.05 with 4 or 5 people
    # (exact minimum p: 2/16, 2/32), and always does with 10 or more.
    strong = np.linspace(1.0, 3.0, 30)
    p = power_curve(strong, sizes, rng=np.random.default_rng(3))
    assert p[0] == 0.0 and p[1] == 0.0
    assert p[3] == 1.0 and p[4] == 1.0


def test_power_grows_with_n_for_a_moderate_shift() -> None:
    rng = np.random.default_rng(5)
    d = rng.normal(0.5, 1.0, 200)
    p = power_curve(d, (8, 16, 32), resamples=2000, rng=np.random.default_rng(6))
    assert p[0] < p[1] < p[2]
    # Normal theory for a one-sample test of a 0.5 SD shift at n = 32 gives ~0.78
    # (t test); the signed-rank test's efficiency is 0.955 of it: within 0.6..0.95.
    assert 0.6 < p[2] < 0.95


def test_bootstrap_ci_covers_the_mean_with_normal_theory_width() -> None:
    rng = np.random.default_rng(11)
    x = rng.normal(10.0, 2.0, 400)
    lo, hi = bootstrap_mean_ci(x, np.random.default_rng(12))
    assert lo < x.mean() < hi
    expected = 2 * 1.96 * x.std(ddof=1) / math.sqrt(x.size)
    assert abs((hi - lo) - expected) / expected < 0.15
    assert bootstrap_mean_ci([3.0, 3.0, 3.0], rng) == (3.0, 3.0)
    assert all(math.isnan(v) for v in bootstrap_mean_ci([1.0], rng))


def test_compare_reports_direction_effect_and_sample_size() -> None:
    xa = np.arange(20, dtype=np.float64) + 2.0
    xb = np.arange(20, dtype=np.float64)
    c = compare("m", "umc", "pec", xa, xb, np.random.default_rng(1), sizes=(4, 6, 8))
    assert c.mean_diff == 2.0 and c.median_diff == 2.0 and c.rank_biserial == 1.0
    assert c.p_value < 0.001
    assert c.n_for_power == 6  # all differences positive: significant from n = 6 on
    none = compare("m", "umc", "pec", xb, xb, np.random.default_rng(1), sizes=(4, 40))
    assert none.p_value == 1.0 and none.n_for_power is None and none.nonzero == 0


def _pairwise_rank_sums(d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R+, the tie term and n by comparing every pair in a row: an independent
    definition of what the compiled sort computes."""
    a = np.abs(d)
    zeros = np.count_nonzero(a == 0.0, axis=1)
    below = (a[:, None, :] < a[:, :, None]).sum(axis=2)
    size = (a[:, None, :] == a[:, :, None]).sum(axis=2)
    ranks = 1.0 + below + (size - 1) / 2.0 - zeros[:, None]
    t_plus = np.where(d > 0.0, ranks, 0.0).sum(axis=1)
    ties = np.where(a > 0.0, size * size - 1.0, 0.0).sum(axis=1)
    return t_plus, ties, (d.shape[1] - zeros).astype(np.float64)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 45), st.integers(1, 30), st.integers(0, 2**16), st.booleans())
def test_sorted_rank_sums_equal_the_pairwise_definition_exactly(
        n: int, rows: int, seed: int, ties: bool) -> None:
    rng = np.random.default_rng(seed)
    d = (rng.integers(-3, 4, size=(rows, n)).astype(np.float64) if ties
         else rng.standard_normal((rows, n)))
    got = _signed_rank_sums(np.ascontiguousarray(d))
    for mine, reference in zip(got, _pairwise_rank_sums(d), strict=True):
        np.testing.assert_array_equal(mine, reference)
