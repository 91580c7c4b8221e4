"""Tests of expected utilities and the decision rule."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from controller.decision.expected_utility import (
    decide,
    decide_fast,
    expected_utilities,
    expected_utilities_into,
    progress_index,
)
from controller.tick_record import Action

tables = arrays(np.float64, (4, 4, 101), elements=st.floats(-1e4, 0.0))
progress = arrays(np.float64, 3, elements=st.floats(0.0, 1.0))
weights = arrays(np.float64, 4, elements=st.floats(0.0, 1.0))


def first_argmax(values: np.ndarray) -> Action:
    best = 0
    for a in range(1, 4):
        if values[a] > values[best]:
            best = a
    return Action(best + 1)


@settings(max_examples=60, deadline=None)
@given(table=tables, s=progress, j=st.integers(0, 3))
def test_certain_model_gives_its_best_action(table: np.ndarray, s: np.ndarray, j: int) -> None:
    post = np.zeros(4)
    post[j] = 1.0
    n = 0 if j == 3 else math.floor(s[j] * 100 + 0.5)
    expected = first_argmax(table[:, j, n])
    assert decide(expected_utilities(table, s, post)) == expected
    out = np.empty(4)
    assert decide_fast(table, s, post, out) == expected


@settings(max_examples=60, deadline=None)
@given(table=tables, s=progress, w=weights)
def test_eu_is_linear_in_the_posteriors(table: np.ndarray, s: np.ndarray, w: np.ndarray) -> None:
    assume(w.sum() > 1e-3)
    p = w / w.sum()
    parts = [expected_utilities(table, s, np.eye(4)[k]) for k in range(4)]
    eu = expected_utilities(table, s, p)
    np.testing.assert_allclose(eu, sum(p[k] * parts[k] for k in range(4)), rtol=1e-9, atol=1e-6)
    # Scaling every posterior scales the EU (homogeneity). Below the smallest normal
    # float (2.2e-308) halving itself rounds (subnormals keep fewer bits), so the
    # tolerance there is that absolute step, not the relative one.
    np.testing.assert_allclose(expected_utilities(table, s, 0.5 * p), 0.5 * eu, rtol=1e-12,
                               atol=np.finfo(np.float64).tiny)


@settings(max_examples=60, deadline=None)
@given(table=tables, s=progress, w=weights)
def test_fast_variant_agrees(table: np.ndarray, s: np.ndarray, w: np.ndarray) -> None:
    out = np.empty(4)
    action = decide_fast(table, s, w, out)
    eu = expected_utilities(table, s, w)
    np.testing.assert_allclose(out, eu, rtol=1e-12, atol=1e-9)
    assert action == first_argmax(out)


def test_eu_by_hand() -> None:
    table = np.zeros((4, 4, 101))
    table[:, 0, 20] = [-10.0, -4.0, -8.0, -9.0]  # squat at s = 0.2
    table[:, 1, 7] = [-10.0, -12.0, -11.0, -3.0]  # stoop_left at s = 0.07
    table[:, 3, :] = [[-1.0], [-50.0], [-30.0], [-30.0]]  # other
    s = np.array([0.2, 0.07, np.nan])
    post = np.array([0.5, 0.25, 0.0, 0.25])
    eu = expected_utilities(table, s, post)
    np.testing.assert_allclose(eu, [-7.75, -17.5, -14.25, -12.75])
    assert decide(eu) == Action.NO_LOCK
    eu2 = expected_utilities(table, s, np.array([0.7, 0.3, 0.0, 0.0]))
    np.testing.assert_allclose(eu2, [-10.0, -6.4, -8.9, -7.2])
    assert decide(eu2) == Action.LOCK_BOTH


def test_ties_go_to_lower_action_number() -> None:
    assert decide(np.array([-1.0, -1.0, -1.0, -1.0])) == Action.NO_LOCK
    assert decide(np.array([-2.0, -1.0, -3.0, -1.0])) == Action.LOCK_BOTH
    assert decide(np.array([-2.0, -3.0, -1.0, -1.0])) == Action.LOCK_RIGHT
    out = np.empty(4)
    assert decide_fast(np.zeros((4, 4, 101)), np.zeros(3), np.full(4, 0.25), out) == 1


def test_progress_index_rounds_to_nearest_and_clips() -> None:
    assert progress_index(0.0) == 0
    assert progress_index(0.004) == 0
    assert progress_index(0.006) == 1
    assert progress_index(0.505) == 51  # halves round up
    assert progress_index(1.0) == 100
    assert progress_index(1.3) == 100
    assert progress_index(-0.2) == 0
    with pytest.raises(ValueError):
        progress_index(math.nan)


def test_nan_progress_only_matters_with_weight() -> None:
    table = np.random.default_rng(1).uniform(-100, 0, (4, 4, 101))
    s = np.array([0.3, np.nan, np.nan])
    post = np.array([0.6, 0.0, 0.0, 0.4])
    eu = expected_utilities(table, s, post)
    assert np.isfinite(eu).all()
    out = np.empty(4)
    decide_fast(table, s, post, out)
    np.testing.assert_allclose(out, eu)
    bad = np.array([0.6, 0.1, 0.0, 0.3])
    with pytest.raises(ValueError):
        expected_utilities(table, s, bad)
    with pytest.raises(ValueError):
        expected_utilities_into(table, s, bad, out)


def test_input_validation() -> None:
    with pytest.raises(ValueError, match="table"):
        expected_utilities(np.zeros((4, 3, 101)), np.zeros(3), np.ones(4) / 4)
    with pytest.raises(ValueError, match="s_curr"):
        expected_utilities(np.zeros((4, 4, 101)), np.zeros(4), np.ones(4) / 4)
    with pytest.raises(ValueError, match="posteriors"):
        expected_utilities(np.zeros((4, 4, 101)), np.zeros(3), np.array([1.0, np.nan, 0, 0]))
    with pytest.raises(ValueError, match="NaN"):
        decide(np.array([0.0, np.nan, 0.0, 0.0]))
