"""Normalisation references and their invariants (Besomi et al. 2020's methods)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.emg.normalisation import (
    Reference,
    exceeds_reference,
    mvc_reference,
    normalise,
    task_reference,
)

FS = 1000.0


def _envelope(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.abs(rng.normal(size=(5000, 3))) * np.array([1e-4, 2e-4, 5e-5]) + 1e-6


def test_mvc_is_the_largest_half_second_average_not_a_spike() -> None:
    env = np.full((4000, 2), 1e-4)
    env[1000:1500, 0] = 5e-4        # a sustained 0.5 s contraction
    env[3000, 0] = 1e-2             # one spike
    env[2000:2499, 1] = 3e-4        # 1 sample short of 0.5 s
    ref = mvc_reference(env, FS, [(500, 3500)], window_s=0.5)
    assert ref[0] == pytest.approx(max(5e-4, (1e-2 + 499 * 1e-4) / 500))
    assert ref[1] == pytest.approx((499 * 3e-4 + 1e-4) / 500)


def test_mvc_window_shorter_than_the_average_is_refused() -> None:
    with pytest.raises(ValueError, match="shorter than"):
        mvc_reference(np.ones((1000, 1)), FS, [(0, 400)], window_s=0.5)


def test_task_exceeding_mvc_is_flagged() -> None:
    env = np.full((6000, 2), 1e-4)
    env[1000:2000] = 4e-4           # MVC trial
    env[4000:4600, 0] = 6e-4        # task above the MVC on channel 0 only
    ref = Reference("mvc", tuple(mvc_reference(env, FS, [(0, 3000)])))
    flag = exceeds_reference(env, FS, [(3000, 6000)], ref)
    assert flag.exceeds == (True, False)
    assert flag.ratio[0] == pytest.approx(1.5)
    assert flag.ratio[1] == pytest.approx(0.25)


@settings(max_examples=25, deadline=None)
@given(k=st.floats(1e-3, 1e3), seed=st.integers(0, 2**16),
       method=st.sampled_from(["mvc", "task_peak", "task_mean"]))
def test_normalised_envelope_does_not_depend_on_the_signal_scale(
        k: float, seed: int, method: str) -> None:
    env = _envelope(seed)

    def normalised(e: np.ndarray) -> np.ndarray:
        if method == "mvc":
            values = mvc_reference(e, FS, [(0, 2000)])
        else:
            values = task_reference(e, [(2000, 3000), (4000, 5000)], method)  # type: ignore[arg-type]
        return normalise(e, Reference(method, tuple(values)))  # type: ignore[arg-type]

    np.testing.assert_allclose(normalised(k * env), normalised(env), rtol=1e-9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**16))
def test_each_reference_maps_to_one(seed: int) -> None:
    env = _envelope(seed)
    windows = [(2000, 3000), (4000, 5000)]
    peak = normalise(env, Reference("task_peak", tuple(task_reference(env, windows, "task_peak"))))
    mean = normalise(env, Reference("task_mean", tuple(task_reference(env, windows, "task_mean"))))
    mvc = normalise(env, Reference("mvc", tuple(mvc_reference(env, FS, [(0, 2000)]))))
    inside = np.vstack([env[a:b] for a, b in windows])
    assert inside.shape[0] == 2000
    np.testing.assert_allclose(np.vstack([peak[a:b] for a, b in windows]).max(axis=0), 1.0)
    np.testing.assert_allclose(np.vstack([mean[a:b] for a, b in windows]).mean(axis=0), 1.0)
    np.testing.assert_allclose(mvc_reference(mvc, FS, [(0, 2000)]), 1.0)
    np.testing.assert_array_equal(normalise(env, Reference.none(3)), env)


def test_reference_must_be_positive_and_state_its_unit() -> None:
    with pytest.raises(ValueError, match=r"channels \[1\]"):
        Reference("mvc", (1.0, 0.0))
    with pytest.raises(ValueError, match="unknown normalisation"):
        Reference("peak", (1.0,))  # type: ignore[arg-type]
    assert Reference("mvc", (2.0,)).to_dict() == {
        "method": "mvc", "unit": "fraction of MVC", "values": [2.0]}
