"""Onset detection: Mahalanobis subsequence DTW between the observation window and a model.

Implements docs/controller-design.md, "Onset detection". Rows `i = 0..M-1` of the DTW matrix are
observations (row `M-1` is the newest), columns `n = 0..N'-1` are model samples.

- Local cost: squared Mahalanobis distance with the model's per-sample 2x2 covariance.
- Step pattern symmetric1: `D(i, n) = c(i, n) + min(D(i-1, n-1), D(i-1, n), D(i, n-1))`.
- Relaxed start on the bottom row (`i = 0`) or the left column (`n = 0`): there `D = c`.
  Since every cost is non-negative, starting there is never worse than arriving there.
- Relaxed end on the top row: `D = min_n D(M-1, n)`; on equal values the smallest `n`
  wins (the least advanced progress estimate).
- Backtracking from that cell to a start cell; tie order diagonal, vertical, horizontal.
  `L` is the number of cells on the path.
- Optional Sakoe-Chiba band of radius `r` cells around the straight line from (0, 0) to
  (M-1, N'-1): cell (i, n) is inside iff `|n - i (N'-1)/(M-1)| <= r`, evaluated exactly
  in integers as `|n (M-1) - i (N'-1)| <= r (M-1)`. Cells outside have infinite cost, so
  start and end cells must lie inside the band too (paper: "inside the adjustment
  window"). With `M = 1` the line degenerates and every cell is inside. A band too
  narrow to connect the bottom to the top row gives `D = inf`, `L = 0` and indices -1.

The hot path is `ModelBank.evaluate`: one compiled call that matches one observation
window against every model and judges the matches, on preallocated buffers, with the
inverse covariances computed once when the bank is built (about 2.5 us per 30x51
model). `match` is the one-shot form (validation and inversion compiled too), for
analysis and tests. `ObservationWindow` keeps the window contiguous without copies.
Every kernel is compiled with `cache=True`; call `warm_up()` before a control loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit

from controller.device.base import SAMPLE_PERIOD_S

#: Samples in a full, time-normalised motion model (docs/controller-design.md).
N_FULL = 101
#: Observation window length: 0.3 s at 100 Hz.
WINDOW = 30

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

# Row layout of the per-model integer outputs, `ModelBank._ints[row, model]`.
_L, _N_START, _N_CURR, _I_START, _I_CURR = range(5)
# Layout of the per-sample precomputed parameters: mean, then the inverse covariance
# [[a, b], [b, c]] as (a, 2b, c), so the cost is a d0^2 + (2b) d0 d1 + c d1^2.
_MU0, _MU1, _IA, _IB, _IC = range(5)


@dataclass(frozen=True, slots=True)
class Match:
    """The best warping path of one observation window against one model.

    `n_*` index model samples (progress `s = n / (N_FULL - 1)`), `i_*` index the
    observation window (`t = i * dt`). Without any path, `D` is inf, `L` 0 and the
    indices are -1.
    """

    D: float
    L: int
    n_start: int
    n_curr: int
    i_start: int
    i_curr: int


@dataclass(frozen=True, slots=True)
class OnsetCriteria:
    """The paper's three acceptance criteria for a match (all configuration).

    Defaults from docs/controller-design.md: `d_max = 30 * 2^2`, every one of 30 observations two
    standard deviations from the mean.
    """

    s_req: float = 0.05
    t_req: float = 0.05
    d_max: float = 120.0

    def __post_init__(self) -> None:
        for name in ("s_req", "t_req", "d_max"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ValueError(f"OnsetCriteria.{name} must be a finite number >= 0, got {v!r}")

    def accepts(self, m: Match, n_full: int = N_FULL, dt: float = SAMPLE_PERIOD_S) -> bool:
        """True iff `s_curr - s_start > s_req`, `t_curr - t_start > t_req` and `D < d_max`.

        Args:
            m: The match to judge.
            n_full: Samples of the full model; progress is `n / (n_full - 1)`.
            dt: Observation sample period in seconds.
        """
        if m.L <= 0:
            return False
        ds = (m.n_curr - m.n_start) / (n_full - 1)
        dt_span = (m.i_curr - m.i_start) * dt
        dist = m.D
        return ds > self.s_req and dt_span > self.t_req and dist < self.d_max


# --------------------------------------------------------------------------- kernels


@njit(cache=True, nogil=True)
def _band_limits(i: int, m_rows: int, n_cols: int, radius: int) -> tuple[int, int]:
    """First and last column of row `i` inside the band (hi < lo if the row is empty)."""
    if radius < 0 or m_rows == 1:
        return 0, n_cols - 1
    den = m_rows - 1
    centre = i * (n_cols - 1)
    lo_num = centre - radius * den
    hi_num = centre + radius * den
    lo = -((-lo_num) // den)  # ceil division
    hi = hi_num // den
    lo = min(max(lo, 0), n_cols)  # the clamps are for safety; lo <= N'-1 and hi >= 0
    hi = min(max(hi, -1), n_cols - 1)
    return lo, hi


@njit(cache=True, nogil=True, inline="always")
def _cost_row(
    x0: float, x1: float, mu0: FloatArray, mu1: FloatArray, ia: FloatArray, ib: FloatArray,
    ic: FloatArray, lo: int, hi: int, out: FloatArray,
) -> None:
    """Squared Mahalanobis cost of one observation to every model sample; inf off-band."""
    for n in range(out.shape[0]):
        d0 = x0 - mu0[n]
        d1 = x1 - mu1[n]
        out[n] = ia[n] * d0 * d0 + ib[n] * d0 * d1 + ic[n] * d1 * d1
    for n in range(0, lo):
        out[n] = np.inf
    for n in range(hi + 1, out.shape[0]):
        out[n] = np.inf


@njit(cache=True, nogil=True)
def _fill(obs: FloatArray, prm: FloatArray, k: int, radius: int, acc: FloatArray) -> None:
    """Accumulated costs `acc[k, :M, :]` of model `k` (parameters `prm[k]`, shape (5, N)).

    First every local cost (a loop the compiler vectorises), then the recurrence in
    place. Off-band cells get infinite local cost, hence infinite D. Rows are scanned
    in pairs, row i+1 one column behind row i: the two add-then-min chains along the
    rows are independent, so the CPU overlaps them.
    """
    m_rows = obs.shape[0]
    n_cols = prm.shape[2]
    mu0 = prm[k, 0]
    mu1 = prm[k, 1]
    ia = prm[k, 2]
    ib = prm[k, 3]
    ic = prm[k, 4]
    for i in range(m_rows):
        lo, hi = _band_limits(i, m_rows, n_cols, radius)
        _cost_row(obs[i, 0], obs[i, 1], mu0, mu1, ia, ib, ic, lo, hi, acc[k, i])
    # Bottom row and left column keep D = c. Each cell below is read as its cost and
    # then overwritten with its accumulated cost.
    i = 1
    while i < m_rows:
        prev = acc[k, i - 1]
        cur = acc[k, i]
        left = cur[0]
        if i + 1 < m_rows and n_cols >= 2:
            nxt = acc[k, i + 1]
            left1 = nxt[0]
            m = prev[0]
            m = prev[1] if prev[1] < m else m
            m = left if left < m else m
            left = cur[1] + m
            cur[1] = left
            for n in range(2, n_cols):
                m = prev[n - 1]
                m = prev[n] if prev[n] < m else m
                m = left if left < m else m
                m1 = cur[n - 2]
                m1 = cur[n - 1] if cur[n - 1] < m1 else m1
                m1 = left1 if left1 < m1 else m1
                left = cur[n] + m
                cur[n] = left
                left1 = nxt[n - 1] + m1
                nxt[n - 1] = left1
            m1 = cur[n_cols - 2]
            m1 = cur[n_cols - 1] if cur[n_cols - 1] < m1 else m1
            m1 = left1 if left1 < m1 else m1
            nxt[n_cols - 1] = nxt[n_cols - 1] + m1
            i += 2
        else:
            for n in range(1, n_cols):
                m = prev[n - 1]
                m = prev[n] if prev[n] < m else m
                m = left if left < m else m
                left = cur[n] + m
                cur[n] = left
            i += 1


@njit(cache=True, nogil=True)
def _trace(
    acc: FloatArray, m_rows: int, k: int, out_d: FloatArray, out_i: IntArray
) -> None:
    """Best end on the top row of model `k`, then backtrack; write D and the path summary."""
    n_cols = acc.shape[2]
    top = m_rows - 1
    best_d = np.inf
    nb = -1
    for n in range(n_cols):
        if acc[k, top, n] < best_d:
            best_d = acc[k, top, n]
            nb = n
    if nb < 0:
        out_d[k] = np.inf
        out_i[0, k] = 0
        for j in range(1, 5):
            out_i[j, k] = -1
        return
    i = top
    n = nb
    length = 1
    while i > 0 and n > 0:
        dg = acc[k, i - 1, n - 1]
        v = acc[k, i - 1, n]
        h = acc[k, i, n - 1]
        if dg <= v and dg <= h:
            i -= 1
            n -= 1
        elif v <= h:
            i -= 1
        else:
            n -= 1
        length += 1
    out_d[k] = best_d
    out_i[0, k] = length
    out_i[1, k] = n
    out_i[2, k] = nb
    out_i[3, k] = i
    out_i[4, k] = top


@njit(cache=True, nogil=True)
def _match_kernel(
    obs: FloatArray, prm: FloatArray, radius: int, acc: FloatArray,
    out_d: FloatArray, out_i: IntArray,
) -> None:
    """Fill and trace every model, without acceptance (the one-shot path)."""
    for k in range(prm.shape[0]):
        _fill(obs, prm, k, radius, acc)
        _trace(acc, obs.shape[0], k, out_d, out_i)


@njit(cache=True, nogil=True)
def bank_kernel(
    obs: FloatArray,
    prm: FloatArray,
    radius: int,
    crit: FloatArray,
    acc: FloatArray,
    out_d: FloatArray,
    out_i: IntArray,
    out_s: FloatArray,
    out_ok: npt.NDArray[np.bool_],
) -> int:
    """Match `obs` against every model and judge each match; -1 if `obs` holds a NaN.

    `crit` = (s_req, t_req, d_max, n_full, dt). `out_s[:, k]` = (s_start, s_curr),
    `out_i[:, k]` = (L, n_start, n_curr, i_start, i_curr). Public: the UMC's compiled
    tick evaluates the bank with it, into the arrays `ModelBank.kernel_arrays` gives.
    """
    m_rows = obs.shape[0]
    for i in range(m_rows):
        if not (math.isfinite(obs[i, 0]) and math.isfinite(obs[i, 1])):
            return -1
    n_models = prm.shape[0]
    s_req = crit[0]
    t_req = crit[1]
    d_max = crit[2]
    s_den = crit[3] - 1.0
    dt = crit[4]
    for k in range(n_models):
        _fill(obs, prm, k, radius, acc)
        _trace(acc, m_rows, k, out_d, out_i)
        if out_i[0, k] > 0:
            s0 = out_i[1, k] / s_den
            s1 = out_i[2, k] / s_den
            out_s[0, k] = s0
            out_s[1, k] = s1
            ds = (out_i[2, k] - out_i[1, k]) / s_den
            dtt = (out_i[4, k] - out_i[3, k]) * dt
            out_ok[k] = ds > s_req and dtt > t_req and out_d[k] < d_max
        else:
            out_s[0, k] = np.nan
            out_s[1, k] = np.nan
            out_ok[k] = False
    return 0


# Error codes of `_invert_into` and `_oneshot` (0 = fine); the index says where.
_E_OBS_NAN, _E_MEAN_NAN, _E_COV_NAN, _E_COV_ASYM, _E_COV_NOT_PD = 1, 2, 3, 4, 5


@njit(cache=True, nogil=True)
def _invert_into(mean: FloatArray, cov: FloatArray, prm: FloatArray) -> tuple[int, int]:
    """Check one model and write its (5, N) table; (error code, model sample index).

    Positive definite means `a > 0` and `det > 1e-12 a c`: a numerically singular
    matrix is rejected rather than inverted into huge numbers. Symmetry is checked to
    a relative 1e-9 of the larger diagonal entry.
    """
    for n in range(mean.shape[0]):
        if not (math.isfinite(mean[n, 0]) and math.isfinite(mean[n, 1])):
            return _E_MEAN_NAN, n
        a = cov[n, 0, 0]
        b = cov[n, 0, 1]
        b2 = cov[n, 1, 0]
        c = cov[n, 1, 1]
        if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(b2) and math.isfinite(c)):
            return _E_COV_NAN, n
        scale = max(abs(a), abs(c), 1e-300)
        if abs(b - b2) > 1e-9 * scale:
            return _E_COV_ASYM, n
        det = a * c - b * b
        if a <= 0.0 or c <= 0.0 or det <= 1e-12 * a * c:
            return _E_COV_NOT_PD, n
        prm[0, n] = mean[n, 0]
        prm[1, n] = mean[n, 1]
        prm[2, n] = c / det
        prm[3, n] = -2.0 * b / det  # twice the off-diagonal: the cost uses it once
        prm[4, n] = a / det
    return 0, -1


@njit(cache=True, nogil=True)
def _oneshot(
    obs: FloatArray, mean: FloatArray, cov: FloatArray, radius: int, out_i: IntArray
) -> tuple[int, int, float]:
    """Validate, invert, fill and trace one model: (error code, index, D); ints in out_i."""
    m_rows = obs.shape[0]
    for i in range(m_rows):
        if not (math.isfinite(obs[i, 0]) and math.isfinite(obs[i, 1])):
            return _E_OBS_NAN, i, np.nan
    n_cols = mean.shape[0]
    prm = np.empty((1, 5, n_cols))
    code, idx = _invert_into(mean, cov, prm[0])
    if code != 0:
        return code, idx, np.nan
    acc = np.empty((1, m_rows, n_cols))
    out_d = np.empty(1)
    _fill(obs, prm, 0, radius, acc)
    _trace(acc, m_rows, 0, out_d, out_i)
    return 0, -1, out_d[0]


# --------------------------------------------------------------------------- validation


def _as_obs(obs: npt.ArrayLike) -> FloatArray:
    a = np.ascontiguousarray(obs, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 1:
        raise ValueError(f"observations must have shape (M, 2) with M >= 1, got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0])
        raise ValueError(f"observations contain NaN or inf (first at observation index {bad})")
    return a


def _raise_for(code: int, idx: int, label: str, cov: FloatArray | None = None) -> None:
    """Turn a kernel error code into the ValueError a caller can act on."""
    if code == _E_OBS_NAN:
        raise ValueError(f"observations contain NaN or inf (first at observation index {idx})")
    what = {
        _E_MEAN_NAN: "mean contains NaN or inf",
        _E_COV_NAN: "cov contains NaN or inf",
        _E_COV_ASYM: "cov is not symmetric",
        _E_COV_NOT_PD: "cov is not positive definite",
    }[code]
    extra = f": {cov[idx].tolist()}" if cov is not None and code == _E_COV_NOT_PD else ""
    raise ValueError(f"{label}: {what} at model sample {idx}{extra}")


def _model_arrays(mean: npt.ArrayLike, cov: npt.ArrayLike, label: str) -> tuple[
    FloatArray, FloatArray
]:
    """Mean (N, 2) and cov (N, 2, 2) as C-contiguous float64, shapes checked."""
    mu = np.ascontiguousarray(mean, dtype=np.float64)
    sg = np.ascontiguousarray(cov, dtype=np.float64)
    if mu.ndim != 2 or mu.shape[1] != 2 or mu.shape[0] < 1:
        raise ValueError(f"{label}: mean must have shape (N, 2), got {mu.shape}")
    n = mu.shape[0]
    if sg.shape != (n, 2, 2):
        raise ValueError(f"{label}: cov must have shape ({n}, 2, 2) to match mean, got {sg.shape}")
    return mu, sg


def _model_params(mean: npt.ArrayLike, cov: npt.ArrayLike, label: str) -> FloatArray:
    """Validate one model and return its (5, N) mean + inverse-covariance table."""
    mu, sg = _model_arrays(mean, cov, label)
    prm = np.empty((5, mu.shape[0]), dtype=np.float64)
    code, idx = _invert_into(mu, sg, prm)
    if code:
        _raise_for(code, idx, label, sg)
    return prm


def _check_band(band: int | None) -> int:
    if band is None:
        return -1
    if isinstance(band, bool) or not isinstance(band, int | np.integer) or band < 0:
        raise ValueError(f"band must be None or an integer radius >= 0, got {band!r}")
    return int(band)


# --------------------------------------------------------------------------- public API


class ModelBank:
    """Several motion models, ready to be matched against one window in one compiled call.

    Build it once per model set (inverse covariances are computed here), call
    `warm_up()` before the control loop, then `evaluate(obs)` every controller tick.
    Results are written into the arrays below, which are reused (copy them to keep them):

    - `D` (K,) float, `L` (K,) int,
    - `n_start`, `n_curr`, `i_start`, `i_curr` (K,) int,
    - `s_start`, `s_curr` (K,) float (progress `n / (n_full - 1)`, NaN without a path),
    - `accepted` (K,) bool (the criteria, judged inside the same call).
    """

    def __init__(
        self,
        means: npt.ArrayLike,
        covs: npt.ArrayLike,
        band: int | None = None,
        criteria: OnsetCriteria | None = None,
        n_full: int = N_FULL,
        dt: float = SAMPLE_PERIOD_S,
        max_window: int = WINDOW,
    ) -> None:
        """Validate the models and precompute their inverse covariances.

        Args:
            means: (K, N, 2) online part of every model's mean.
            covs: (K, N, 2, 2) matching 2x2 covariance blocks.
            band: Sakoe-Chiba radius in cells, None for the full matrix.
            criteria: Acceptance criteria (defaults in docs/controller-design.md).
            n_full: Samples of the full model, for progress values.
            dt: Observation sample period in seconds.
            max_window: Largest observation window `evaluate` will be given.
        """
        mu = np.asarray(means, dtype=np.float64)
        sg = np.asarray(covs, dtype=np.float64)
        if mu.ndim != 3 or mu.shape[0] < 1:
            raise ValueError(f"means must have shape (K, N, 2), got {mu.shape}")
        if sg.ndim != 4 or sg.shape[0] != mu.shape[0]:
            raise ValueError(
                f"covs must have shape (K, N, 2, 2) with K={mu.shape[0]}, got {sg.shape}"
            )
        if n_full < 2 or n_full < mu.shape[1]:
            raise ValueError(f"n_full must be >= 2 and >= the model length, got {n_full}")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt!r}")
        if max_window < 1:
            raise ValueError(f"max_window must be >= 1, got {max_window}")
        self.criteria = criteria if criteria is not None else OnsetCriteria()
        self.band = band
        self.n_full = int(n_full)
        self.dt = float(dt)
        self._radius = _check_band(band)
        # (K, 5, N): one contiguous row per parameter, so the cost loop vectorises.
        self._prm = np.ascontiguousarray(
            np.stack([_model_params(mu[k], sg[k], f"model {k}") for k in range(mu.shape[0])])
        )
        k_models, n_cols = self._prm.shape[0], self._prm.shape[2]
        self.n_models = k_models
        self.n_samples = n_cols
        self.max_window = int(max_window)
        c = self.criteria
        self._crit = np.array([c.s_req, c.t_req, c.d_max, float(n_full), float(dt)])
        self._acc = np.empty((k_models, self.max_window, n_cols), dtype=np.float64)
        self.D = np.full(k_models, np.inf)
        # Rows, not columns, per quantity: every public array below is C-contiguous,
        # the layout the compiled consumers (intent, decision) were warmed up with.
        self._ints = np.zeros((5, k_models), dtype=np.int64)
        self._s = np.full((2, k_models), np.nan)
        self.accepted = np.zeros(k_models, dtype=np.bool_)
        # Views on the integer table, so callers read named arrays.
        self.L = self._ints[_L]
        self.n_start = self._ints[_N_START]
        self.n_curr = self._ints[_N_CURR]
        self.i_start = self._ints[_I_START]
        self.i_curr = self._ints[_I_CURR]
        self.s_start = self._s[0]
        self.s_curr = self._s[1]

    def warm_up(self) -> None:
        """Compile (or load from the numba cache) now, so no tick ever pays for it."""
        obs = np.repeat(self._prm[0, :2, :1].T, min(self.max_window, WINDOW), axis=0)
        self.evaluate(obs)

    def evaluate(self, obs: FloatArray) -> None:
        """Match one window (M, 2), oldest first, against every model; fill the outputs.

        Only cheap checks run here (this is the hot path): `obs` must be a C-contiguous
        float64 (M, 2) array with `M <= max_window`; NaN raises ValueError.
        """
        if (
            obs.ndim != 2
            or obs.shape[1] != 2
            or not 1 <= obs.shape[0] <= self.max_window
            or obs.dtype != np.float64
            or not obs.flags.c_contiguous
        ):
            obs = _as_obs(obs)
            if obs.shape[0] > self.max_window:
                raise ValueError(f"window of {obs.shape[0]} > max_window={self.max_window}")
        rc = bank_kernel(
            obs, self._prm, self._radius, self._crit, self._acc,
            self.D, self._ints, self._s, self.accepted,
        )
        if rc != 0:
            _as_obs(obs)  # raises with the offending index
            raise ValueError("observations contain NaN or inf")

    @property
    def radius(self) -> int:
        """The Sakoe-Chiba radius as the kernels take it (-1: no band)."""
        return self._radius

    def kernel_arrays(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray,
                                     IntArray, FloatArray, npt.NDArray[np.bool_]]:
        """(parameters, criteria, scratch, D, ints, s, accepted): the arguments of
        `bank_kernel` after the window and radius, for a compiled caller (the control
        tick) that evaluates the bank into these very arrays."""
        return (self._prm, self._crit, self._acc, self.D, self._ints, self._s, self.accepted)

    def match(self, k: int) -> Match:
        """The last `evaluate` result for model `k` as a `Match`."""
        L, n_start, n_curr, i_start, i_curr = self._ints[:, k].tolist()
        return Match(float(self.D[k]), L, n_start, n_curr, i_start, i_curr)

    def ensure_window(self, m_rows: int) -> None:
        """Grow the scratch buffer so that windows of `m_rows` observations fit."""
        if m_rows > self.max_window:
            self.max_window = int(m_rows)
            self._acc = np.empty(
                (self.n_models, self.max_window, self.n_samples), dtype=np.float64
            )

    def cost_matrix(self, obs: npt.ArrayLike, k: int) -> FloatArray:
        """The accumulated-cost matrix of model `k` for `obs` (for plots and tests)."""
        a = _as_obs(obs)
        acc = np.empty((self.n_models, a.shape[0], self.n_samples), dtype=np.float64)
        d = np.empty(self.n_models)
        ints = np.empty((5, self.n_models), dtype=np.int64)
        _match_kernel(a, self._prm, self._radius, acc, d, ints)
        return acc[k].copy()


class OnsetDetector:
    """One model, precomputed; `match(obs)` per window. A one-model `ModelBank`."""

    def __init__(
        self, mean: npt.ArrayLike, cov: npt.ArrayLike, band: int | None = None,
        n_full: int = N_FULL,
    ) -> None:
        """Args: mean (N, 2), cov (N, 2, 2), band radius or None, full model length."""
        self.bank = ModelBank(
            np.asarray(mean, dtype=np.float64)[None], np.asarray(cov, dtype=np.float64)[None],
            band=band, n_full=n_full,
        )

    def warm_up(self) -> None:
        """Compile now, never inside a tick."""
        self.bank.warm_up()

    def match(self, obs: npt.ArrayLike) -> Match:
        """Best path of the observations (M, 2), oldest first, against the model."""
        a = np.ascontiguousarray(obs, dtype=np.float64)
        if a.ndim == 2 and a.shape[0] > self.bank.max_window:
            self.bank.ensure_window(a.shape[0])
        self.bank.evaluate(a)
        return self.bank.match(0)


def match(
    obs: npt.ArrayLike, mean: npt.ArrayLike, cov: npt.ArrayLike, band: int | None = None
) -> Match:
    """Match observations (M, 2) against one model: mean (N, 2), cov (N, 2, 2).

    One-shot convenience: validates and inverts the covariances on every call. A
    controller should hold a `ModelBank` instead.
    """
    a = np.ascontiguousarray(obs, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 1:
        raise ValueError(f"observations must have shape (M, 2) with M >= 1, got {a.shape}")
    mu, sg = _model_arrays(mean, cov, "model")
    ints = np.empty(5, dtype=np.int64)
    code, idx, d = _oneshot(a, mu, sg, _check_band(band), ints.reshape(5, 1))
    if code:
        _raise_for(code, idx, "model", sg)
    L, n_start, n_curr, i_start, i_curr = ints.tolist()
    return Match(d, L, n_start, n_curr, i_start, i_curr)


@njit("void(float64[:, ::1], int64[::1], float64, float64)", cache=True, nogil=True)
def window_push(buf: FloatArray, pos_count: IntArray, q_left: float, q_right: float) -> None:
    """Append one sample to the doubled ring `buf` (2M, 2); `pos_count` = (next slot, count).

    The one implementation of the window: `ObservationWindow` and the compiled control
    tick (`controller.kernel.tick`) both call it, and read it with `window_start`.
    """
    size = buf.shape[0] // 2
    p = pos_count[0]
    buf[p, 0] = q_left
    buf[p, 1] = q_right
    buf[p + size, 0] = q_left
    buf[p + size, 1] = q_right
    p += 1
    pos_count[0] = 0 if p == size else p
    if pos_count[1] < size:
        pos_count[1] += 1


@njit(cache=True, nogil=True, inline="always")
def window_start(size: int, pos_count: IntArray) -> int:
    """First row of the window in the doubled ring; it ends at row `pos + size`."""
    return pos_count[0] + size - pos_count[1]


class ObservationWindow:
    """The last `M` calibrated hip angles, oldest first, as a contiguous (M, 2) array.

    A doubled ring buffer: every push writes two slots, so `view()` is always a
    contiguous slice, with no copy and no allocation per tick.
    """

    def __init__(self, size: int = WINDOW) -> None:
        """Args: size: window length in samples (30 = 0.3 s at 100 Hz)."""
        if size < 1:
            raise ValueError(f"window size must be >= 1, got {size}")
        self.size = size
        self.buffer = np.zeros((2 * size, 2), dtype=np.float64)
        #: (next slot, samples held), the array `window_push` updates.
        self.pos_count = np.zeros(2, dtype=np.int64)

    def push(self, q_left: float, q_right: float) -> None:
        """Append the newest sample, dropping the oldest once full."""
        window_push(self.buffer, self.pos_count, float(q_left), float(q_right))

    @property
    def full(self) -> bool:
        """True once `size` samples have been pushed since the last reset."""
        return bool(self.pos_count[1] == self.size)

    def __len__(self) -> int:
        return int(self.pos_count[1])

    def view(self) -> FloatArray:
        """The window, oldest first: (len, 2), valid until the next push."""
        pos = int(self.pos_count[0])
        return self.buffer[pos + self.size - int(self.pos_count[1]) : pos + self.size]

    def reset(self) -> None:
        """Forget all samples."""
        self.pos_count[:] = 0
