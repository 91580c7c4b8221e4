"""The safety bound on priors: no usage history makes the UMC lock where equal priors
would not (docs/personalisation.md). Worst-case posteriors, the simulator's walking and
stairs evaluations, and counter-examples showing the tests can fail."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.controllers.umc import UMC
from controller.decision.expected_utility import LOCK_MARGIN, decide_fast, lock_margin
from controller.decision.utility_function import UtilitySet
from controller.evaluation.cohort import trial_recording
from controller.intent.label_shift import learn_from_unconfirmed
from controller.intent.learned_priors import learn_from_confirmed
from controller.intent.motion_model import ModelSet
from controller.intent.posteriors import posteriors
from controller.intent.prior_safety import ClassRole, PriorBounds, class_roles, lock_decided
from controller.runner.replay import replay_columns
from controller.sim.participant import VirtualParticipant
from controller.tick_record import CATEGORY_NAMES, MODEL_NAMES

EQUAL = np.full(4, 0.25)
#: Adversarial and ordinary confirmed-use histories.
HISTORIES = st.one_of(
    st.integers(0, 400).map(lambda n: ["stoop_left"] * n),
    st.integers(0, 400).map(lambda n: ["squat"] * n),
    st.integers(0, 400).map(lambda n: ["stoop_right"] * n),
    st.integers(0, 400).map(lambda n: ["other"] * n),
    st.lists(st.sampled_from(CATEGORY_NAMES), max_size=300),
)


@pytest.fixture(scope="module")
def sets(default_sets: tuple[Path, Path]) -> tuple[ModelSet, UtilitySet]:
    from backend import bootstrap
    models, folder = default_sets
    return ModelSet.load(models), UtilitySet.load(bootstrap.utilities_path(folder, 25.0))


@pytest.fixture(scope="module")
def table(sets: tuple[ModelSet, UtilitySet]) -> np.ndarray:
    return np.ascontiguousarray(sets[1].table.values)


@pytest.fixture(scope="module")
def bounds(table: np.ndarray) -> PriorBounds:
    return PriorBounds.for_table(table)


@pytest.fixture(scope="module")
def gait(sets: tuple[ModelSet, UtilitySet]) -> tuple[np.ndarray, np.ndarray]:
    """(s_curr, p_obs) of every UMC evaluation in walking and stairs trials of twelve
    virtual participants (the DTW does not depend on the priors)."""
    s_all, p_all = [], []
    for seed in range(1, 13):
        p = VirtualParticipant.from_seed(seed)
        for script in ("walking", "stairs"):
            cols = replay_columns(trial_recording(p, seed, script, 0), UMC(*sets))
            ran = cols["controller_ran"]
            s_all.append(np.stack([cols[f"s_curr_{n}"] for n in MODEL_NAMES], 1)[ran])
            p_all.append(np.stack([cols[f"p_obs_{n}"] for n in MODEL_NAMES], 1)[ran])
    return np.concatenate(s_all), np.concatenate(p_all)


def random_evaluations(seed: int, m: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Worst-case-style evaluations: any progress, likelihoods with exact 0s and 1s."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, 1, (m, 3))
    p[rng.uniform(size=(m, 3)) < 0.2] = 0.0
    p[rng.uniform(size=(m, 3)) < 0.05] = 1.0
    return rng.uniform(0, 1, (m, 3)), p


def test_roles_of_the_default_utilities(table: np.ndarray) -> None:
    assert class_roles(table) == (ClassRole.FAVOURS_LOCK, ClassRole.MIXED, ClassRole.MIXED,
                                  ClassRole.OPPOSES_LOCK)


def test_vectorised_decision_is_the_controllers(table: np.ndarray) -> None:
    s, p = random_evaluations(0, 300)
    pri = np.array([0.1, 0.3, 0.3, 0.3])
    got = lock_decided(table, s, p, pri)
    out = np.zeros(4)
    want = [decide_fast(table, s[i], posteriors(p[i], pri), out, lock_margin(pri)) > 1
            for i in range(len(p))]
    assert got.tolist() == want
    assert 0 < got.sum() < len(got)


#: Found by search over the default utilities: with safe learned priors the EU of
#: locking the right side exceeds no lock by rounding alone (the true margin is below
#: 1e-12 of the terms), where equal priors tie or stay free.
ROUNDING_CASE = (
    [0.0833, 0.2624, 0.2624, 0.3919],
    [0.005619807260905432, 0.04744748755238358, 2.800694509833761e-09],
    [0.676, 0.632, 0.45],
)


def test_rounding_cannot_make_learned_priors_lock_where_equal_priors_do_not(
        table: np.ndarray) -> None:
    pri, p_obs, s = (np.array(v) for v in ROUNDING_CASE)
    assert PriorBounds.for_table(table).violation(pri) is None
    out = np.zeros(4)
    equal = decide_fast(table, s, posteriors(p_obs, EQUAL), out, lock_margin(EQUAL))
    assert equal == 1
    # Without the margin the controller's own decision locks here: the case is real.
    assert decide_fast(table, s, posteriors(p_obs, pri), out) > 1
    assert decide_fast(table, s, posteriors(p_obs, pri), out, lock_margin(pri)) == 1
    assert not lock_decided(table, s[None], p_obs[None], pri)[0]
    assert lock_margin(EQUAL) == 0.0 and lock_margin(pri) == LOCK_MARGIN


@settings(max_examples=60, deadline=None)
@given(est=st.lists(st.floats(0, 1), min_size=4, max_size=4).filter(lambda v: sum(v) > 0))
def test_projection_lands_in_the_set_and_keeps_it(bounds: PriorBounds, est: list[float]) -> None:
    e = np.array(est) / sum(est)
    pr = bounds.project(e)
    assert bounds.violation(pr) is None
    assert pr[3] >= 0.25  # corollary: other never below its equal share
    assert (pr >= 0.05).all()
    assert np.array_equal(bounds.project(pr), pr)
    assert np.linalg.norm(pr - e) <= np.linalg.norm(EQUAL - e) + 1e-9  # no worse than equal


@settings(max_examples=40, deadline=None)
@given(history=HISTORIES, seed=st.integers(0, 2**31))
def test_no_confirmed_history_adds_a_lock_on_any_evaluation(
        table: np.ndarray, bounds: PriorBounds, history: list[str], seed: int) -> None:
    pri = learn_from_confirmed(history, bounds).values
    s, p = random_evaluations(seed)
    equal, learned = lock_decided(table, s, p, EQUAL), lock_decided(table, s, p, pri)
    assert not (learned & ~equal).any()


@settings(max_examples=25, deadline=None)
@given(history=HISTORIES, unconfirmed=st.integers(0, 2**31))
def test_no_history_adds_a_lock_in_simulated_walking_or_stairs(
        table: np.ndarray, bounds: PriorBounds, gait: tuple[np.ndarray, np.ndarray],
        history: list[str], unconfirmed: int) -> None:
    s, p = gait
    equal = lock_decided(table, s, p, EQUAL)
    rng = np.random.default_rng(unconfirmed)
    skew = rng.dirichlet(np.full(4, 0.3), size=50)  # every motion left unconfirmed
    for pri in (learn_from_confirmed(history, bounds).values,
                learn_from_unconfirmed(skew, EQUAL, bounds).values):
        learned = lock_decided(table, s, p, pri)
        assert not (learned & ~equal).any()
        assert learned.sum() <= equal.sum()


def test_unbounded_priors_do_add_walking_and_stairs_locks(
        table: np.ndarray, bounds: PriorBounds, gait: tuple[np.ndarray, np.ndarray]) -> None:
    """The counter-example: every lift confirmed as stoop left, without the bound."""
    s, p = gait
    raw = learn_from_confirmed(["stoop_left"] * 400, bounds)
    equal = lock_decided(table, s, p, EQUAL).sum()
    assert lock_decided(table, s, p, raw.estimate).sum() > equal > 0
    assert lock_decided(table, s, p, raw.values).sum() <= equal


def test_other_at_its_equal_share_is_not_enough(table: np.ndarray, bounds: PriorBounds) -> None:
    """'Lock classes' total <= 3/4 and other >= 1/4' still adds locks: the stoops
    must share one prior."""
    loose = np.array([0.05, 0.65, 0.05, 0.25])
    assert bounds.violation(loose) is not None
    s, p = random_evaluations(7, 20000)
    added = lock_decided(table, s, p, loose) & ~lock_decided(table, s, p, EQUAL)
    assert added.any()


def test_safe_priors_can_raise_the_stoops(table: np.ndarray, bounds: PriorBounds) -> None:
    """Learning is not frozen: a wearer who never squats gets higher stoop priors."""
    pr = learn_from_confirmed(["stoop_left", "stoop_right", "other"] * 100, bounds).values
    assert pr[1] == pr[2] > 0.25 and pr[0] < 0.25
    s, p = random_evaluations(3, 5000)
    assert not (lock_decided(table, s, p, pr) & ~lock_decided(table, s, p, EQUAL)).any()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 200),
       point=st.sampled_from(CATEGORY_NAMES), sharp=st.floats(0.0, 1.0))
def test_no_unconfirmed_use_adds_a_lock_on_any_evaluation(
        table: np.ndarray, bounds: PriorBounds, seed: int, n: int, point: str,
        sharp: float) -> None:
    """Unconfirmed use, however it looks (posteriors that all point at one category, to
    any degree, mixed with noise): the EM estimate, bounded, adds no lock on worst-case
    evaluations, and refuses nothing the equal priors would not."""
    rng = np.random.default_rng(seed)
    post = rng.dirichlet(np.full(4, 0.5), size=n)
    post = (1 - sharp) * post + sharp * np.eye(4)[CATEGORY_NAMES.index(point)]
    pri = learn_from_unconfirmed(post, EQUAL, bounds).values
    s, p = random_evaluations(seed)
    equal, learned = lock_decided(table, s, p, EQUAL), lock_decided(table, s, p, pri)
    assert not (learned & ~equal).any()
