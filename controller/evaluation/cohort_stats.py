"""Statistics of a virtual cohort: distributions, paired comparisons, power curves.

- Distributions: each metric's mean per controller with a bootstrap 95 % confidence
  interval (scipy's BCa bootstrap over participants).
- Paired comparisons: the same participants use every controller, and the paper's
  metrics are small counts or bounded percentages per participant, often tied and far
  from normal, so the test is the Wilcoxon signed-rank test (two-sided, zero
  differences dropped as Wilcoxon did), with the matched-pairs rank-biserial
  correlation as effect size: r = (R+ - R-) / (R+ + R-) over the ranks of the non-zero
  |differences| (+1: every participant higher with the first controller). p-values
  use the normal approximation with tie and continuity corrections (counts tie often,
  where the exact distribution does not apply), the same in the cohort's test and in
  every resampled study of the power curves.
- Power: for a study of n participants (4..40), the probability that the test finds the
  difference at alpha 0.05, estimated by drawing n participants with replacement from
  the virtual cohort's paired differences many times and testing each draw. The
  sample size for 80 % power is the smallest n whose estimate reaches it.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import stats

FloatArray = NDArray[np.float64]

ALPHA = 0.05
POWER_TARGET = 0.8
POWER_SIZES: tuple[int, ...] = tuple(range(4, 41))
#: Draws per sample size: the power estimate's standard error is at most
#: sqrt(0.25 / 1000) = 1.6 percentage points.
POWER_RESAMPLES = 1000
BOOTSTRAP_RESAMPLES = 2000


@dataclass(frozen=True)
class MetricSummary:
    """One metric of one controller over the cohort."""

    controller: str
    metric: str
    n: int
    mean: float
    sd: float
    median: float
    ci_low: float
    ci_high: float


@dataclass(frozen=True)
class Comparison:
    """A paired comparison of two controllers on one metric (`a` minus `b`)."""

    metric: str
    a: str
    b: str
    n: int
    nonzero: int
    mean_diff: float
    ci_low: float
    ci_high: float
    median_diff: float
    statistic: float
    p_value: float
    rank_biserial: float
    #: Power at each of `sizes`.
    power: tuple[float, ...]
    sizes: tuple[int, ...]

    @property
    def n_for_power(self) -> int | None:
        """Smallest n with power >= 0.8 (None: not within the sizes tried)."""
        for n, p in zip(self.sizes, self.power, strict=True):
            if p >= POWER_TARGET:
                return n
        return None


def _finite(x: Sequence[float] | FloatArray) -> FloatArray:
    a = np.asarray(x, dtype=np.float64)
    return a[np.isfinite(a)]


def bootstrap_mean_ci(x: Sequence[float] | FloatArray, rng: np.random.Generator,
                      resamples: int = BOOTSTRAP_RESAMPLES,
                      level: float = 0.95) -> tuple[float, float]:
    """Bootstrap (BCa) confidence interval of the mean; NaNs are ignored. Constant
    data give the point itself; fewer than two values give NaN."""
    a = _finite(x)
    if a.size < 2:
        return math.nan, math.nan
    if np.all(a == a[0]):
        return float(a[0]), float(a[0])
    with warnings.catch_warnings():
        # BCa warns (and returns NaN) on a degenerate jackknife; fall back below.
        warnings.simplefilter("ignore")
        res = stats.bootstrap((a,), np.mean, n_resamples=resamples, confidence_level=level,
                              method="BCa", vectorized=True, rng=rng)
        lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if not (math.isfinite(lo) and math.isfinite(hi)):
            res = stats.bootstrap((a,), np.mean, n_resamples=resamples,
                                  confidence_level=level, method="percentile",
                                  vectorized=True, rng=rng)
            lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    return lo, hi


def summarise(controller: str, metric: str, values: FloatArray,
              rng: np.random.Generator) -> MetricSummary:
    """Mean, SD, median and bootstrap CI of one metric over the participants."""
    a = _finite(values)
    lo, hi = bootstrap_mean_ci(a, rng)
    return MetricSummary(controller, metric, int(a.size),
                         float(a.mean()) if a.size else math.nan,
                         float(a.std(ddof=1)) if a.size > 1 else math.nan,
                         float(np.median(a)) if a.size else math.nan, lo, hi)


def rank_biserial(d: Sequence[float] | FloatArray) -> float:
    """Matched-pairs rank-biserial correlation of paired differences `d` (zeros
    dropped, ties given their mean rank); NaN when every difference is zero."""
    a = _finite(d)
    a = a[a != 0.0]
    if a.size == 0:
        return math.nan
    ranks = stats.rankdata(np.abs(a))
    plus, minus = float(ranks[a > 0].sum()), float(ranks[a < 0].sum())
    return (plus - minus) / (plus + minus)


@njit(cache=True, nogil=True)
def _signed_rank_sums(d: Any) -> tuple[Any, Any, Any]:  # pragma: no cover - compiled
    """Per row of `d`: the sum of the ranks of the positive differences among the
    non-zero |differences| (ties at their mean rank), the tie term sum(t^3 - t) over
    the non-zero tie groups, and the number of non-zero differences.

    One insertion sort per row: a tie group at sorted positions i..j-1 has mean rank
    (i + j + 1) / 2 among all values, less the number of zeros (which sort first)
    among the non-zeros. (The pairwise comparison this replaces held n x n values per
    row: 80 % of a 100-participant cohort's analysis time.)"""
    rows, cols = d.shape
    t_plus = np.zeros(rows)
    ties = np.zeros(rows)
    n = np.zeros(rows)
    a = np.empty(cols)  # |differences| of the row, sorted
    pos = np.empty(cols, dtype=np.bool_)  # whether each sorted one was positive
    for r in range(rows):
        for k in range(cols):  # insertion sort: rows are a few dozen long
            v = abs(d[r, k])
            up = d[r, k] > 0.0
            i = k
            while i > 0 and a[i - 1] > v:
                a[i] = a[i - 1]
                pos[i] = pos[i - 1]
                i -= 1
            a[i] = v
            pos[i] = up
        zeros = 0
        while zeros < cols and a[zeros] == 0.0:
            zeros += 1
        n[r] = cols - zeros
        i = zeros
        while i < cols:
            j = i + 1
            while j < cols and a[j] == a[i]:
                j += 1
            rank = (i + j + 1) / 2.0 - zeros
            positives = 0
            for k in range(i, j):
                if pos[k]:
                    positives += 1
            t_plus[r] += rank * positives
            t = j - i
            ties[r] += t * t * t - t
            i = j
    return t_plus, ties, n


def wilcoxon_p(d: FloatArray) -> FloatArray:
    """Two-sided Wilcoxon signed-rank p-value of each row of `d` (rows: samples,
    columns: participants), zero differences dropped, by the normal approximation with
    the tie and continuity corrections; 1.0 where a row has no non-zero difference.

    The same test as `scipy.stats.wilcoxon(row, zero_method="wilcox", method="approx",
    correction=True)` (the tests check it row by row), vectorised: a power curve tests
    tens of thousands of resampled studies. The continuity correction keeps it close
    to the exact test at small n (n = 5, all differences positive: 0.059 against the
    exact 0.0625). The rank sums are sums of half-integers, exact in float64, so the
    way they are summed does not change a p-value.
    """
    d = np.ascontiguousarray(np.atleast_2d(np.asarray(d, dtype=np.float64)))
    t_plus, ties, n = _signed_rank_sums(d)
    mean = n * (n + 1) / 4.0
    var = n * (n + 1) * (2 * n + 1) / 24.0 - ties / 48.0
    dev = t_plus - mean
    dev = dev - 0.5 * np.sign(dev)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(var > 0.0, dev / np.sqrt(np.where(var > 0.0, var, 1.0)), 0.0)
    p = 2.0 * stats.norm.sf(np.abs(z))
    return np.where(n > 0, np.minimum(p, 1.0), 1.0)


def power_curve(d: Sequence[float] | FloatArray, sizes: Sequence[int] = POWER_SIZES,
                alpha: float = ALPHA, resamples: int = POWER_RESAMPLES,
                rng: np.random.Generator | None = None) -> tuple[float, ...]:
    """Probability that a study of n participants finds the difference (Wilcoxon,
    two-sided, `alpha`), for each n in `sizes`, by resampling the differences `d`."""
    a = _finite(d)
    rng = rng if rng is not None else np.random.default_rng(0)
    if a.size < 2:
        return tuple(math.nan for _ in sizes)
    out: list[float] = []
    for n in sizes:
        draws = a[rng.integers(0, a.size, size=(resamples, n))]
        out.append(float(np.mean(wilcoxon_p(draws) < alpha)))
    return tuple(out)


def compare(metric: str, a: str, b: str, xa: FloatArray, xb: FloatArray,
            rng: np.random.Generator, sizes: Sequence[int] = POWER_SIZES,
            resamples: int = POWER_RESAMPLES) -> Comparison:
    """Paired comparison of controllers `a` and `b` (same participants, same order)."""
    xa, xb = np.asarray(xa, dtype=np.float64), np.asarray(xb, dtype=np.float64)
    keep = np.isfinite(xa) & np.isfinite(xb)
    d = xa[keep] - xb[keep]
    nonzero = int(np.count_nonzero(d))
    stat, p = math.nan, 1.0
    if nonzero:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = stats.wilcoxon(d, zero_method="wilcox", method="approx", correction=True)
        stat, p = float(res.statistic), float(res.pvalue)
    lo, hi = bootstrap_mean_ci(d, rng)
    return Comparison(metric, a, b, int(d.size), nonzero,
                      float(d.mean()) if d.size else math.nan, lo, hi,
                      float(np.median(d)) if d.size else math.nan, stat, p,
                      rank_biserial(d), power_curve(d, sizes, ALPHA, resamples, rng),
                      tuple(sizes))
