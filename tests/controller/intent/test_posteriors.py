"""Tests of likelihoods and posteriors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from controller.intent.posteriors import (
    IntentEstimator,
    check_priors,
    likelihood,
    likelihood_nb,
    p_other,
    posteriors,
)


def test_paper_example() -> None:
    assert round(likelihood(7.5, 3), 4) == 0.2771


@pytest.mark.parametrize("L", [1, 2, 3, 5, 10, 30, 80, 200, 500])
def test_closed_form_equals_scipy_chi2_sf(L: int) -> None:
    for D in np.concatenate([[0.0, 1e-9, 0.1], np.linspace(0.5, 6.0 * L + 40, 60)]):
        want = chi2.sf(D, df=2 * L)
        got = likelihood(float(D), L)
        if want > 1e-300:
            assert got == pytest.approx(want, rel=1e-10, abs=0.0), (D, L)
        else:
            assert got < 1e-290


def test_large_arguments_do_not_underflow_too_early() -> None:
    # exp(-x) alone underflows for x > 745; the tail here is still of order 1.
    assert likelihood(1600.0, 900) == pytest.approx(chi2.sf(1600.0, 1800), rel=1e-9)
    assert likelihood(1600.0, 900) > 0.5
    assert likelihood(math.inf, 3) == 0.0
    assert likelihood(0.0, 3) == 1.0


def test_likelihood_rejects_bad_input() -> None:
    for D, L in [(math.nan, 3), (-1.0, 3), (1.0, 0), (1.0, 2.5)]:
        with pytest.raises(ValueError):
            likelihood(D, L)  # type: ignore[arg-type]
    assert math.isnan(likelihood_nb(math.nan, 3))


def test_p_other_is_product_of_complements() -> None:
    assert p_other([0.2, 0.5, 0.0]) == pytest.approx(0.8 * 0.5 * 1.0)
    assert p_other([0.0, 0.0, 0.0]) == 1.0
    with pytest.raises(ValueError):
        p_other([0.2, 1.5, 0.0])


def test_posteriors_by_hand() -> None:
    post = posteriors([0.5, 0.2, 0.0], [0.25, 0.25, 0.25, 0.25])
    ev = np.array([0.5, 0.2, 0.0, 0.5 * 0.8])
    assert post == pytest.approx(ev / ev.sum())
    # No accepted match at all: everything is `other`.
    assert posteriors([0.0, 0.0, 0.0]).tolist() == [0.0, 0.0, 0.0, 1.0]


def test_zero_evidence_falls_back_to_other() -> None:
    # Squat fits perfectly (p_other = 0) but has prior 0: Bayes is 0/0.
    post = posteriors([1.0, 0.0, 0.0], [0.0, 0.5, 0.5, 0.0])
    assert post.tolist() == [0.0, 0.0, 0.0, 1.0]


probs = st.floats(0.0, 1.0, allow_nan=False)


@st.composite
def priors_st(draw: st.DrawFn) -> np.ndarray:
    w = np.array([draw(st.floats(0.01, 10.0)) for _ in range(4)])
    return w / w.sum()


@settings(max_examples=200, deadline=None)
@given(st.lists(probs, min_size=3, max_size=3), priors_st())
def test_posteriors_sum_to_one(p: list[float], pr: np.ndarray) -> None:
    post = posteriors(p, pr)
    assert post.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(post >= 0)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(0.01, 0.99), min_size=3, max_size=3), priors_st(), priors_st(),
    st.integers(0, 3), st.integers(0, 3),
)
def test_priors_move_posteriors_as_bayes_rule_says(
    p: list[float], pr1: np.ndarray, pr2: np.ndarray, a: int, b: int
) -> None:
    """post_a / post_b = (e_a pr_a) / (e_b pr_b): changing priors scales the ratio by
    exactly the ratio of the prior ratios."""
    q1, q2 = posteriors(p, pr1), posteriors(p, pr2)
    lhs = (q2[a] / q2[b]) / (q1[a] / q1[b])
    rhs = (pr2[a] / pr2[b]) / (pr1[a] / pr1[b])
    assert lhs == pytest.approx(rhs, rel=1e-9)
    ev = np.array([*p, np.prod(1 - np.array(p))])
    assert q1[a] / q1[b] == pytest.approx(ev[a] * pr1[a] / (ev[b] * pr1[b]), rel=1e-9)


@pytest.mark.parametrize(
    "bad",
    [[0.25, 0.25, 0.25], [0.5, 0.5, 0.5, -0.5], [0.3, 0.3, 0.3, 0.3], [math.nan, 0.5, 0.25, 0.25],
     [math.inf, 0, 0, 0]],
)
def test_bad_priors_rejected(bad: list[float]) -> None:
    with pytest.raises(ValueError, match="priors"):
        check_priors(bad)
    with pytest.raises(ValueError, match="priors"):
        posteriors([0.1, 0.1, 0.1], bad)
    with pytest.raises(ValueError, match="priors"):
        IntentEstimator(bad)


def test_estimator_matches_the_functions() -> None:
    est = IntentEstimator([0.1, 0.2, 0.3, 0.4])
    est.warm_up()
    D = np.array([7.5, 20.0, 3.0])
    L = np.array([3, 12, 30], dtype=np.int64)
    acc = np.array([True, True, False])
    post = est.update(D, L, acc)
    p = [likelihood(7.5, 3), likelihood(20.0, 12), 0.0]
    assert est.p_obs == pytest.approx(p, rel=1e-12)
    assert post == pytest.approx(posteriors(p, [0.1, 0.2, 0.3, 0.4]), rel=1e-12)
    assert post is est.post
