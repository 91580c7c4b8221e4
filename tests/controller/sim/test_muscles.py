"""Muscle activation of the simulated wearer: bounds, the exoskeleton's effect as a known
truth, scaling with the body, and reproducibility by seed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.sim.muscles import BASELINE, CHANNELS, MAX_NM_PER_KG, MuscleModel
from controller.sim.participant import VirtualParticipant

ES = [i for i, (m, _) in enumerate(CHANNELS) if m.startswith("erector_spinae")]
HIP = [i for i, (m, _) in enumerate(CHANNELS) if m in ("gluteus_maximus", "biceps_femoris")]
BASE = np.array([BASELINE[m] for m, _ in CHANNELS])


@pytest.fixture(scope="module")
def squat() -> tuple[MuscleModel, np.ndarray]:
    ex = SimulatedExoskeleton(seed=3, script="squat-sequence")
    return MuscleModel.for_participant(ex.participant), ex.trajectory.torque


moments = st.floats(-300.0, 400.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(moments, moments, moments, moments), min_size=1, max_size=20),
       st.integers(0, 10_000))
def test_activation_is_within_baseline_and_one(rows: list[tuple[float, ...]], seed: int) -> None:
    model = MuscleModel.for_participant(VirtualParticipant.from_seed(seed))
    arr = np.array(rows)
    a = model.activation(arr[:, :2], arr[:, 2:])
    assert a.shape == (len(rows), 12)
    assert np.all(a >= BASE - 1e-12) and np.all(a <= 1.0)


def test_exoskeleton_torque_equal_to_the_moment_leaves_only_baseline(
        squat: tuple[MuscleModel, np.ndarray]) -> None:
    model, torque = squat
    without = model.activation(torque, np.zeros_like(torque))
    full = model.activation(torque, torque)
    assert without[:, ES].max() > 0.3  # a squat lift needs the back
    np.testing.assert_allclose(full, np.broadcast_to(BASE, full.shape), atol=1e-12)


def test_support_lowers_agonists_in_proportion(squat: tuple[MuscleModel, np.ndarray]) -> None:
    model, torque = squat
    a0 = model.activation(torque, np.zeros_like(torque))
    a3 = model.activation(torque, 0.3 * torque)
    peak = int(np.argmax(torque.sum(axis=1)))
    above0 = a0[peak, ES + HIP] - BASE[ES + HIP]
    above3 = a3[peak, ES + HIP] - BASE[ES + HIP]
    # Below saturation the part above baseline is linear in the net moment.
    assert np.all(a0[peak, ES + HIP] < 1.0)
    np.testing.assert_allclose(above3, 0.7 * above0, rtol=1e-9)


def test_support_on_one_side_unloads_that_hip_and_both_backs() -> None:
    model = MuscleModel.from_body(75.0)
    m = np.array([[120.0, 120.0]])
    base = model.activation(m, np.zeros((1, 2)))[0]
    left = model.activation(m, np.array([[40.0, 0.0]]))[0]
    lh = [i for i in HIP if CHANNELS[i][1] == "left"]
    rh = [i for i in HIP if CHANNELS[i][1] == "right"]
    assert np.all(left[lh] < base[lh]) and np.allclose(left[rh], base[rh])
    assert np.all(left[ES] < base[ES])  # the trunk brace relieves both erector spinae


def test_flexion_demand_drives_the_flexors_not_the_extensors() -> None:
    model = MuscleModel.from_body(75.0)
    a = model.activation(np.array([[-60.0, 0.0]]), np.zeros((1, 2)))[0]
    rf_left = CHANNELS.index(("rectus_femoris", "left"))
    rf_right = CHANNELS.index(("rectus_femoris", "right"))
    assert a[rf_left] > a[rf_right] + 0.05
    gm_left = CHANNELS.index(("gluteus_maximus", "left"))
    assert a[gm_left] == pytest.approx(BASELINE["gluteus_maximus"])


def test_nominal_maxima_scale_with_body_mass_and_follow_the_table() -> None:
    light, heavy = MuscleModel.from_body(60.0), MuscleModel.from_body(90.0)
    for ch in CHANNELS:
        assert heavy.max_nm[ch] == pytest.approx(1.5 * light.max_nm[ch])
    # Both sides' erector spinae together make the trunk's maximum.
    es = sum(v for (m, _), v in light.max_nm.items() if m.startswith("erector_spinae"))
    assert es == pytest.approx(MAX_NM_PER_KG["lumbar_extension"] * 60.0)
    woman = MuscleModel.from_body(60.0, sex="female")
    assert woman.max_nm[CHANNELS[0]] < light.max_nm[CHANNELS[0]]


def test_reproducible_by_seed_and_different_between_people() -> None:
    p = VirtualParticipant.from_seed(7)
    assert MuscleModel.for_participant(p) == MuscleModel.for_participant(p)
    q = VirtualParticipant.from_seed(8)
    assert MuscleModel.for_participant(p).max_nm != MuscleModel.for_participant(q).max_nm


def test_shapes_are_checked() -> None:
    with pytest.raises(ValueError, match=r"\(K, 2\)"):
        MuscleModel.from_body(70.0).activation(np.zeros((3, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="positive"):
        MuscleModel.from_body(0.0)
