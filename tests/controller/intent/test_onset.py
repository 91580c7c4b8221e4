"""Tests of the Mahalanobis subsequence DTW against independent references."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import numpy as np
import pytest
from dtaidistance import dtw_ndim
from dtaidistance.subsequence.dtw import subsequence_alignment
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from controller.intent.onset import (
    Match,
    ModelBank,
    ObservationWindow,
    OnsetCriteria,
    OnsetDetector,
    bank_kernel,
    match,
)
from controller.intent.posteriors import IntentEstimator, intent_kernel

# --------------------------------------------------------------------------- references

Problem = tuple[np.ndarray, np.ndarray, np.ndarray, int | None]


def ref_in_band(i: int, n: int, m_rows: int, n_cols: int, band: int | None) -> bool:
    """Band membership straight from the definition, in floating point."""
    if band is None or m_rows == 1:
        return True
    centre = i * (n_cols - 1) / (m_rows - 1)
    return abs(n - centre) <= band + 1e-9


def ref_costs(
    obs: np.ndarray, mean: np.ndarray, cov: np.ndarray, band: int | None
) -> list[list[float]]:
    m_rows, n_cols = len(obs), len(mean)
    c = [[math.inf] * n_cols for _ in range(m_rows)]
    for i in range(m_rows):
        for n in range(n_cols):
            if ref_in_band(i, n, m_rows, n_cols, band):
                d = obs[i] - mean[n]
                c[i][n] = float(d @ np.linalg.solve(cov[n], d))
    return c


def ref_match(obs: np.ndarray, mean: np.ndarray, cov: np.ndarray, band: int | None) -> Match:
    """Plain-Python DP and backtracking written from docs/controller-design.md."""
    c = ref_costs(obs, mean, cov, band)
    m_rows, n_cols = len(c), len(c[0])
    D = [[math.inf] * n_cols for _ in range(m_rows)]
    for i in range(m_rows):
        for n in range(n_cols):
            if i == 0 or n == 0:
                D[i][n] = c[i][n]
            else:
                D[i][n] = c[i][n] + min(D[i - 1][n - 1], D[i - 1][n], D[i][n - 1])
    top = D[m_rows - 1]
    best = min(top)
    if math.isinf(best):
        return Match(math.inf, 0, -1, -1, -1, -1)
    n_end = top.index(best)
    i, n, length = m_rows - 1, n_end, 1
    while i > 0 and n > 0:
        options = [
            (D[i - 1][n - 1], i - 1, n - 1),
            (D[i - 1][n], i - 1, n),
            (D[i][n - 1], i, n - 1),
        ]
        lowest = min(o[0] for o in options)
        _, i, n = next(o for o in options if o[0] == lowest)
        length += 1
    return Match(best, length, n, n_end, i, m_rows - 1)


def all_paths(m_rows: int, n_cols: int) -> Iterator[list[tuple[int, int]]]:
    """Every admissible path: start on the bottom row or left column, end on the top row."""
    starts = {(0, n) for n in range(n_cols)} | {(i, 0) for i in range(m_rows)}

    def extend(path: list[tuple[int, int]]) -> Iterator[list[tuple[int, int]]]:
        i, n = path[-1]
        if i == m_rows - 1:
            yield list(path)
        for di, dn in ((1, 1), (1, 0), (0, 1)):
            ni, nn = i + di, n + dn
            if ni < m_rows and nn < n_cols:
                path.append((ni, nn))
                yield from extend(path)
                path.pop()

    for s in sorted(starts):
        yield from extend([s])


# --------------------------------------------------------------------------- strategies


@st.composite
def problems(
    draw: st.DrawFn, max_m: int = 12, max_n: int = 16, integer: bool = False
) -> Problem:
    m_rows = draw(st.integers(1, max_m))
    n_cols = draw(st.integers(1, max_n))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    if integer:  # coarse values and identity covariances: many exact ties
        obs = rng.integers(0, 3, size=(m_rows, 2)).astype(float)
        mean = rng.integers(0, 3, size=(n_cols, 2)).astype(float)
        cov = np.tile(np.eye(2), (n_cols, 1, 1))
    else:
        obs = rng.normal(size=(m_rows, 2))
        mean = rng.normal(size=(n_cols, 2))
        a = rng.normal(size=(n_cols, 2, 2))
        cov = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(2)
    band = draw(st.one_of(st.none(), st.integers(0, n_cols)))
    return obs, mean, cov, band


def assert_same(got: Match, want: Match) -> None:
    assert (got.L, got.n_start, got.n_curr, got.i_start, got.i_curr) == (
        want.L, want.n_start, want.n_curr, want.i_start, want.i_curr,
    )
    if math.isinf(want.D):
        assert math.isinf(got.D)
    else:
        assert float(got.D) == pytest.approx(want.D, rel=1e-10, abs=1e-12)


# --------------------------------------------------------------------------- tests


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(problems())
def test_matches_reference_on_random_problems(p: Problem) -> None:
    obs, mean, cov, band = p
    assert_same(match(obs, mean, cov, band=band), ref_match(obs, mean, cov, band))


@settings(max_examples=300, deadline=None)
@given(problems(integer=True))
def test_matches_reference_with_many_ties(p: Problem) -> None:
    obs, mean, cov, band = p
    assert_same(match(obs, mean, cov, band=band), ref_match(obs, mean, cov, band))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.one_of(st.none(), st.integers(1, 10)))
def test_full_size_problem_matches_reference(seed: int, band: int | None) -> None:
    rng = np.random.default_rng(seed)
    mean = np.cumsum(rng.normal(size=(51, 2)) * 0.05, axis=0)
    a = rng.normal(size=(51, 2, 2)) * 0.05
    cov = a @ a.transpose(0, 2, 1) + 1e-3 * np.eye(2)
    start = int(rng.integers(0, 30))
    obs = mean[start : start + 30] + rng.normal(size=(min(30, 51 - start), 2)) * 0.02
    assert_same(match(obs, mean, cov, band=band), ref_match(obs, mean, cov, band))


@settings(max_examples=60, deadline=None)
@given(problems(max_m=4, max_n=4))
def test_d_is_the_minimum_over_all_admissible_paths(p: Problem) -> None:
    """Exhaustive check of the DP itself, and that the reported path summary is optimal."""
    obs, mean, cov, _ = p
    c = ref_costs(obs, mean, cov, None)
    best = math.inf
    summaries: dict[tuple[int, int, int, int, int], float] = {}
    for path in all_paths(len(obs), len(mean)):
        cost = sum(c[i][n] for i, n in path)
        best = min(best, cost)
        key = (len(path), path[0][1], path[-1][1], path[0][0], path[-1][0])
        summaries[key] = min(summaries.get(key, math.inf), cost)
    m = match(obs, mean, cov)
    assert float(m.D) == pytest.approx(best, rel=1e-10, abs=1e-12)
    assert summaries[(m.L, m.n_start, m.n_curr, m.i_start, m.i_curr)] == pytest.approx(
        m.D, rel=1e-10, abs=1e-12
    )


def test_path_can_start_on_the_left_column() -> None:
    """Observations that only match the model start late in the window."""
    mean = np.column_stack([np.linspace(0.0, 1.0, 51), np.linspace(0.0, 1.0, 51)])
    cov = np.tile(np.eye(2) * 1e-2, (51, 1, 1))
    obs = np.full((30, 2), 5.0)  # far from every model sample ...
    obs[20:] = mean[:10]  # ... except the last ten, which follow the model from s = 0
    m = match(obs, mean, cov)
    assert m.n_start == 0 and m.i_start == 20 and m.i_curr == 29
    assert m.n_curr == 9 and m.L == 10 and float(m.D) == pytest.approx(0.0, abs=1e-12)
    assert m == ref_match(obs, mean, cov, None)


def _one_d(values: list[float]) -> np.ndarray:
    return np.column_stack([values, np.zeros(len(values))]).astype(float)


def test_tie_order_prefers_diagonal_over_vertical_and_horizontal() -> None:
    # Costs [[0,0,1],[0,0,1],[1,1,0]]: from (1,1) all three predecessors hold 0.
    obs, mean = _one_d([2, 2, 1]), _one_d([2, 2, 1])
    m = match(obs, mean, np.tile(np.eye(2), (3, 1, 1)))
    assert m == Match(D=0.0, L=3, n_start=0, n_curr=2, i_start=0, i_curr=2)


def test_tie_order_prefers_vertical_over_horizontal() -> None:
    # D = [[4,1,0,0],[1,1,1,1],[4,2,1,1]]: end at n=2 (first minimum), diagonal to (1,1),
    # where vertical (0,1) and horizontal (1,0) both hold 1 and the diagonal 4.
    obs, mean = _one_d([2, 1, 2]), _one_d([0, 1, 2, 2])
    m = match(obs, mean, np.tile(np.eye(2), (4, 1, 1)))
    assert m == Match(D=1.0, L=3, n_start=1, n_curr=2, i_start=0, i_curr=2)


def test_end_tie_takes_the_smallest_progress() -> None:
    obs, mean = _one_d([5, 5]), _one_d([0, 5, 5])
    m = match(obs, mean, np.tile(np.eye(2), (3, 1, 1)))
    assert m == Match(D=0.0, L=2, n_start=1, n_curr=1, i_start=0, i_curr=1)


def test_mahalanobis_cost_uses_the_covariance() -> None:
    mean = np.zeros((1, 2))
    cov = np.array([[[4.0, 1.0], [1.0, 2.0]]])
    obs = np.array([[1.0, -2.0]])
    want = float(obs[0] @ np.linalg.inv(cov[0]) @ obs[0])
    assert float(match(obs, mean, cov).D) == pytest.approx(want, rel=1e-12)
    assert want == pytest.approx(22.0 / 7.0)


def test_band_excludes_cells_and_too_narrow_band_gives_no_path() -> None:
    rng = np.random.default_rng(3)
    mean, obs = rng.normal(size=(51, 2)), rng.normal(size=(30, 2))
    cov = np.tile(np.eye(2), (51, 1, 1))
    bank = ModelBank(mean[None], cov[None], band=2)
    acc = bank.cost_matrix(obs, 0)
    for i, n in itertools.product(range(30), range(51)):
        assert math.isinf(acc[i, n]) == (abs(n - i * 50 / 29) > 2)
    # Radius 0: only (0, 0) and (29, 50) are on the line, no connected path exists.
    none = match(obs, mean, cov, band=0)
    assert math.isinf(none.D) and none.L == 0 and none.n_start == -1 and none.i_curr == -1
    assert not OnsetCriteria().accepts(none)


# --------------------------------------------------------------------------- dtaidistance


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 12), st.integers(1, 16), st.integers(0, 2**32 - 1))
def test_identity_covariance_equals_dtaidistance(m_rows: int, n_cols: int, seed: int) -> None:
    """With identity covariances the cost is dtaidistance's squared Euclidean inner cost.

    dtaidistance reports sqrt of the accumulated squared distances; `keep_int_repr`
    returns the accumulated value itself, which is our D. psi = (M, 0, N, N) relaxes the
    start over the whole left column and bottom row and the end over the top row.
    Its subsequence search only relaxes the model side (bottom-row starts), so its
    distance squared bounds ours from above and equals it when our path starts on
    the bottom row. Its default penalty (0.1) is set to 0 to get symmetric1.
    """
    rng = np.random.default_rng(seed)
    obs, mean = rng.normal(size=(m_rows, 2)), rng.normal(size=(n_cols, 2))
    m = match(obs, mean, np.tile(np.eye(2), (n_cols, 1, 1)))
    d_all, _ = dtw_ndim.warping_paths(
        obs, mean, psi=(m_rows, 0, n_cols, n_cols), keep_int_repr=True, psi_neg=False
    )
    assert float(m.D) == pytest.approx(d_all, rel=1e-10, abs=1e-12)
    sa = subsequence_alignment(obs, mean, penalty=0.0)
    d_sub = sa.best_match(minlength=1).distance ** 2
    assert float(m.D) <= d_sub * (1 + 1e-10) + 1e-12
    if m.i_start == 0:
        assert float(m.D) == pytest.approx(d_sub, rel=1e-9, abs=1e-12)


# --------------------------------------------------------------------------- criteria


@pytest.mark.parametrize(
    ("n_start", "n_curr", "i_start", "D", "ok"),
    [
        (0, 6, 0, 10.0, True),
        (0, 5, 0, 10.0, False),  # s span exactly 0.05 is not > 0.05
        (10, 16, 22, 10.0, True),  # spans measured from the path's start, not from 0
        (0, 6, 24, 10.0, False),  # t span 5 samples = 0.05 s, not enough
        (0, 6, 23, 10.0, True),
        (0, 6, 0, 120.0, False),  # D must be strictly below d_max
        (0, 6, 0, 119.999, True),
    ],
)
def test_acceptance_criteria(n_start: int, n_curr: int, i_start: int, D: float, ok: bool) -> None:
    m = Match(D=D, L=30, n_start=n_start, n_curr=n_curr, i_start=i_start, i_curr=29)
    assert OnsetCriteria().accepts(m) is ok


def test_criteria_are_configurable_and_validated() -> None:
    m = Match(D=50.0, L=30, n_start=0, n_curr=3, i_start=0, i_curr=29)
    assert not OnsetCriteria().accepts(m)
    assert OnsetCriteria(s_req=0.02).accepts(m)
    assert not OnsetCriteria(s_req=0.02, d_max=40.0).accepts(m)
    assert OnsetCriteria(s_req=0.02, t_req=0.25).accepts(m, dt=0.01)
    assert not OnsetCriteria(s_req=0.02, t_req=0.3).accepts(m)
    for bad in ({"s_req": -0.1}, {"t_req": math.nan}, {"d_max": math.inf}):
        with pytest.raises(ValueError, match="must be a finite number"):
            OnsetCriteria(**bad)


# --------------------------------------------------------------------------- bank


def _models(seed: int = 0, k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    means = np.cumsum(rng.normal(size=(k, 51, 2)) * 0.03, axis=1)
    a = rng.normal(size=(k, 51, 2, 2)) * 0.05
    return means, a @ a.transpose(0, 1, 3, 2) + 1e-3 * np.eye(2)


@pytest.mark.parametrize("band", [None, 6])
def test_bank_equals_single_model_matches_and_judges_them(band: int | None) -> None:
    means, covs = _models()
    crit = OnsetCriteria()
    bank = ModelBank(means, covs, band=band, criteria=crit)
    bank.warm_up()
    rng = np.random.default_rng(1)
    n_accepted = 0
    for trial in range(20):
        k_true = trial % 3
        s0 = int(rng.integers(0, 25))
        if band is None:  # half speed from a random point of the model
            idx = np.repeat(np.arange(s0, s0 + 15), 2)
        else:  # the band is centred on the whole model: follow its diagonal
            idx = np.round(np.linspace(0, 50, 30)).astype(int)
        obs = np.ascontiguousarray(means[k_true, idx] + rng.normal(size=(30, 2)) * 0.01)
        bank.evaluate(obs)
        for k in range(3):
            want = match(obs, means[k], covs[k], band=band)
            assert bank.match(k) == want
            assert bank.accepted[k] == crit.accepts(want)
            assert bank.s_curr[k] == pytest.approx(want.n_curr / 100)
            assert bank.s_start[k] == pytest.approx(want.n_start / 100)
        n_accepted += int(bank.accepted[k_true])
    assert n_accepted >= 10  # the scenario does produce accepted matches


def test_detector_and_bank_validate_inputs() -> None:
    means, covs = _models(k=1)
    bad = covs.copy()
    bad[0, 7] = [[1.0, 2.0], [2.0, 1.0]]  # symmetric, indefinite
    with pytest.raises(ValueError, match="not positive definite at model sample 7"):
        ModelBank(means, bad)
    bad = covs.copy()
    bad[0, 9, 0, 1] += 1.0
    with pytest.raises(ValueError, match="not symmetric at model sample 9"):
        OnsetDetector(means[0], bad[0])
    bad = covs.copy()
    bad[0, 4, 1, 1] = math.nan
    with pytest.raises(ValueError, match="NaN or inf at model sample 4"):
        match(np.zeros((3, 2)), means[0], bad[0])
    with pytest.raises(ValueError, match=r"shape \(51, 2, 2\)"):
        match(np.zeros((3, 2)), means[0], covs[0, :50])
    with pytest.raises(ValueError, match=r"shape \(M, 2\)"):
        match(np.zeros((3, 3)), means[0], covs[0])
    obs = np.zeros((30, 2))
    obs[12, 1] = math.nan
    with pytest.raises(ValueError, match="observation index 12"):
        match(obs, means[0], covs[0])
    bank = ModelBank(means, covs)
    with pytest.raises(ValueError, match="observation index 12"):
        bank.evaluate(obs)
    with pytest.raises(ValueError, match="band"):
        ModelBank(means, covs, band=-1)


def test_detector_matches_function_and_grows_its_window() -> None:
    means, covs = _models(seed=5, k=1)
    det = OnsetDetector(means[0], covs[0], band=None)
    det.warm_up()
    rng = np.random.default_rng(2)
    for m_rows in (1, 30, 45):
        obs = rng.normal(size=(m_rows, 2)) * 0.1
        assert det.match(obs) == match(obs, means[0], covs[0])


def test_observation_window_is_oldest_first_and_contiguous() -> None:
    w = ObservationWindow(4)
    assert len(w) == 0 and not w.full
    for t in range(3):
        w.push(t, -t)
    assert w.view().tolist() == [[0, 0], [1, -1], [2, -2]]
    for t in range(3, 11):
        w.push(t, -t)
        v = w.view()
        assert v.flags.c_contiguous and v.shape == (4, 2)
        assert v[:, 0].tolist() == [t - 3, t - 2, t - 1, t]
    assert w.full
    w.reset()
    assert len(w) == 0 and w.view().shape == (0, 2)


def test_no_compilation_after_warm_up_in_a_tick() -> None:
    """The outputs a tick hands on are C-contiguous, the layout warm-up compiled for."""
    means, covs = _models(seed=7)
    bank, intent, window = ModelBank(means, covs), IntentEstimator(), ObservationWindow(30)
    bank.warm_up()
    intent.warm_up()
    before = (len(bank_kernel.signatures), len(intent_kernel.signatures))
    for q in means[1, :40]:
        window.push(float(q[0]), float(q[1]))
        bank.evaluate(window.view())
        intent.update(bank.D, bank.L, bank.accepted)
    assert (len(bank_kernel.signatures), len(intent_kernel.signatures)) == before
    for arr in (bank.D, bank.L, bank.s_curr, bank.s_start, bank.accepted, intent.post):
        assert arr.flags.c_contiguous
