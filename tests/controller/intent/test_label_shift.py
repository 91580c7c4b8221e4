"""Saerens et al.'s EM estimate of priors under label shift, and its test."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.intent.label_shift import em_priors


def calibrated_posteriors(true_priors: np.ndarray, train: np.ndarray, n: int,
                          seed: int) -> np.ndarray:
    """Posteriors of a calibrated classifier (Gaussian classes, known likelihoods) that
    was trained with `train` priors, on data drawn with `true_priors`."""
    rng = np.random.default_rng(seed)
    centres = np.arange(len(train)) * 1.5
    y = rng.choice(len(train), size=n, p=true_priors)
    x = rng.normal(centres[y], 1.0)
    lik = np.exp(-0.5 * (x[:, None] - centres[None, :]) ** 2)
    post = lik * train
    return np.asarray(post / post.sum(axis=1, keepdims=True))


def test_recovers_shifted_priors_and_the_test_sees_the_shift() -> None:
    train = np.full(4, 0.25)
    true = np.array([0.1, 0.5, 0.1, 0.3])
    est = em_priors(calibrated_posteriors(true, train, 20000, 1), train)
    assert est.converged
    assert np.abs(est.priors - true).max() < 0.03
    assert est.p_value < 1e-6 and est.dof == 3


def test_no_shift_no_significant_change() -> None:
    train = np.array([0.2, 0.3, 0.3, 0.2])
    est = em_priors(calibrated_posteriors(train, train, 5000, 2), train)
    assert np.abs(est.priors - train).max() < 0.05
    assert est.p_value > 0.01


def test_iteration_cap_is_reported() -> None:
    post = calibrated_posteriors(np.array([0.7, 0.1, 0.1, 0.1]), np.full(4, 0.25), 500, 3)
    est = em_priors(post, np.full(4, 0.25), tol=1e-15, max_iter=2)
    assert est.iterations == 2 and not est.converged


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 60))
def test_estimate_is_a_distribution_and_never_lowers_the_likelihood(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    post = rng.dirichlet(np.full(4, 0.5), size=n)
    post = post / post.sum(axis=1, keepdims=True)
    est = em_priors(post, np.full(4, 0.25))
    assert est.priors.sum() == pytest.approx(1.0) and (est.priors >= 0).all()
    assert est.log_likelihood_ratio >= -1e-9  # EM starts at the training priors
    assert 0.0 <= est.p_value <= 1.0


def test_bad_input_is_named() -> None:
    with pytest.raises(ValueError, match="row 1 sums"):
        em_priors([[0.5, 0.5], [0.5, 0.6]], [0.5, 0.5])
    with pytest.raises(ValueError, match="train_priors"):
        em_priors([[0.5, 0.5]], [1.0, 0.0])
    with pytest.raises(ValueError, match="n >= 1"):
        em_priors(np.zeros((0, 4)), np.full(4, 0.25))
