"""Personal model sets: MAP adaptation of the population models and participant-only fits."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.intent.motion_model import ModelSet, fit_model_set, time_normalise
from controller.intent.personal_models import (
    TooFewDemonstrationsError,
    adapt_model_set,
    fit_participant_model_set,
)
from controller.tick_record import MODEL_NAMES

AMPLITUDE = {"squat": (1.6, 1.6), "stoop_left": (1.3, 0.9), "stoop_right": (0.9, 1.3)}


def demos(seed: int, n: int, scale: float = 1.0) -> dict[str, list[np.ndarray]]:
    """`n` lifts per motion: half-sine flexion, random depth, length and shape noise."""
    rng = np.random.default_rng(seed)
    out: dict[str, list[np.ndarray]] = {}
    for name, (al, ar) in AMPLITUDE.items():
        segs = []
        for _ in range(n):
            k = int(rng.integers(150, 250))
            s = np.sin(np.linspace(0, np.pi, k)) ** rng.uniform(0.8, 1.2)
            amp = scale * rng.uniform(0.85, 1.15)
            segs.append(np.stack([al * amp * s, ar * amp * s], 1) + rng.normal(0, 0.01, (k, 2)))
        out[name] = segs
    return out


POPULATION = fit_model_set(demos(0, 30), version="pop-1")


def test_no_demonstrations_is_the_population_model() -> None:
    adapted = adapt_model_set(POPULATION, {}, tau=5.0)
    for name in MODEL_NAMES:
        assert np.array_equal(adapted[name].mean, POPULATION[name].mean)
        assert np.array_equal(adapted[name].cov, POPULATION[name].cov)
    assert adapted.meta["personal"]["population_version"] == "pop-1"


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 12), tau=st.floats(0.1, 50.0))
def test_adapted_mean_is_the_map_weighting(seed: int, n: int, tau: float) -> None:
    user = demos(seed, n, scale=0.7)
    adapted = adapt_model_set(POPULATION, user, tau=tau)
    for name in MODEL_NAMES:
        xbar = np.mean([time_normalise(x) for x in user[name]], axis=0)
        mu = POPULATION[name].mean
        assert np.allclose(adapted[name].mean, (tau * mu + n * xbar) / (tau + n), atol=1e-12)
        # The distance to the wearer's own mean is the population's, shrunk by tau/(tau+n).
        gap = np.linalg.norm(adapted[name].mean - xbar)
        assert gap == pytest.approx(tau / (tau + n) * np.linalg.norm(mu - xbar), rel=1e-9)


def test_more_demonstrations_approach_the_participant_only_fit() -> None:
    user = demos(9, 40, scale=0.7)
    own = fit_participant_model_set(user, participant="P9")
    gaps = []
    for n in (0, 3, 5, 10, 40):
        adapted = adapt_model_set(POPULATION, {k: v[:n] for k, v in user.items()}, tau=5.0)
        gaps.append(np.linalg.norm(adapted["squat"].mean - own["squat"].mean))
    assert all(a > b for a, b in zip(gaps, gaps[1:], strict=False))
    assert gaps[-1] < 0.15 * gaps[0]


def test_provenance_and_round_trip() -> None:
    user = demos(3, 3)
    ids = {k: [f"P3:{k}:{i}" for i in range(3)] for k in MODEL_NAMES}
    adapted = adapt_model_set(POPULATION, user, tau=4.0, demo_ids=ids, participant="P3")
    p = adapted.meta["personal"]
    assert p["tau"] == 4.0 and p["participant_demonstrations"]["squat"] == ids["squat"]
    assert adapted.demonstrations["squat"][-3:] == ids["squat"]
    assert adapted.fit_params["adaptation"] == "map-mean"
    again = ModelSet.from_json(adapted.to_json())
    assert np.array_equal(again["stoop_left"].mean, adapted["stoop_left"].mean)


def test_too_few_demonstrations_are_named() -> None:
    user = demos(4, 2)
    with pytest.raises(TooFewDemonstrationsError, match=r"at least 3 .*squat: 2"):
        fit_participant_model_set(user)
    with pytest.raises(ValueError, match="tau must be a positive"):
        adapt_model_set(POPULATION, user, tau=0.0)
    with pytest.raises(ValueError, match="stoop_left, demonstration 0"):
        adapt_model_set(POPULATION, {"stoop_left": [np.full((5, 2), np.nan)]})
