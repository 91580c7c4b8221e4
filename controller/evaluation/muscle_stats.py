"""Muscle-activity statistics: reduction against a baseline, and repeated measures.

The input is one value per participant, condition and channel (a participant's mean
over their lifts of a per-lift EMG outcome; channel = f"{muscle}_{side}").

- Reduction: each participant's reduction of a condition against a baseline,
  100 * (1 - condition / baseline), so the number is free of the normalisation's
  scale (MVC, task peak or raw volts give the same reductions). Over the participants:
  the mean with its 95 % Student t interval, and a paired test that is the same
  question the interval answers: a one-sample t-test of the per-participant reductions
  against 0 (p < alpha exactly when the interval excludes 0). The family of tests is
  every channel x condition compared with the baseline in one call; Holm's step-down
  correction (Holm 1979, Scand J Stat) keeps its family-wise error at alpha.
- Repeated measures: per channel, the Friedman test across all conditions (ranks
  within each participant, tie-corrected), the non-parametric test of a repeated-
  measures design that needs no sphericity or normality of EMG amplitudes.

Pure numpy/scipy: the virtual cohort, the study's results and the replication report
use the same numbers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

REDUCTION_TEST = "one-sample t-test of the per-participant reduction against 0 (paired)"
REPEATED_TEST = "Friedman chi-square (ranks within participant, tie-corrected)"


def _jsonable(d: dict[str, Any]) -> dict[str, Any]:
    """NaN and infinities become None (JSON has no NaN); tuples become lists."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            out[k] = None
        elif isinstance(v, tuple):
            out[k] = list(v)
        else:
            out[k] = v
    return out


@dataclass(frozen=True)
class OutcomeRow:
    """One participant's mean over their lifts, one condition, one channel."""

    participant: str
    condition: str
    channel: str
    value: float


@dataclass(frozen=True)
class Reduction:
    """A condition against a baseline on one channel (positive: less activity)."""

    channel: str
    condition: str
    baseline: str
    n: int
    mean_pct: float
    ci_low: float
    ci_high: float
    p_value: float
    p_holm: float
    test: str

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready fields (NaN as None)."""
        return _jsonable(asdict(self))


@dataclass(frozen=True)
class RepeatedMeasures:
    """Across all conditions on one channel."""

    channel: str
    conditions: tuple[str, ...]
    n: int
    test: str
    statistic: float
    df: int
    p_value: float

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready fields (NaN as None, conditions as a list)."""
        return _jsonable(asdict(self))


def _table(rows: Sequence[OutcomeRow]) -> tuple[
        list[str], list[str], dict[tuple[str, str], dict[str, float]]]:
    """Channels and conditions in order of first appearance, and values by
    (channel, condition) then participant. A duplicate row is an error: each row is
    already a participant's mean."""
    channels: dict[str, None] = {}
    conditions: dict[str, None] = {}
    values: dict[tuple[str, str], dict[str, float]] = {}
    for r in rows:
        channels.setdefault(r.channel, None)
        conditions.setdefault(r.condition, None)
        cell = values.setdefault((r.channel, r.condition), {})
        if r.participant in cell:
            raise ValueError(
                f"duplicate outcome for participant {r.participant!r}, condition "
                f"{r.condition!r}, channel {r.channel!r}: give one mean per participant")
        cell[r.participant] = float(r.value)
    return list(channels), list(conditions), values


def holm(p: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values; NaN entries stay NaN and are not counted
    in the family."""
    idx = [i for i, v in enumerate(p) if math.isfinite(v)]
    m = len(idx)
    out = [math.nan] * len(p)
    running = 0.0
    for rank, i in enumerate(sorted(idx, key=lambda j: p[j])):
        running = max(running, min(1.0, (m - rank) * p[i]))
        out[i] = running
    return out


def mean_t_interval(x: Sequence[float] | FloatArray, alpha: float = 0.05
                    ) -> tuple[float, float, float, float]:
    """Mean, its (1 - alpha) Student t interval and the two-sided one-sample t-test
    p-value against 0. Fewer than two values: NaN interval and p. No spread: the
    interval is the point; p is 1 at 0 and 0 elsewhere (the t statistic's limit)."""
    a = np.asarray(x, dtype=np.float64)
    if a.size == 0:
        return math.nan, math.nan, math.nan, math.nan
    mean = float(a.mean())
    if a.size < 2:
        return mean, math.nan, math.nan, math.nan
    sd = float(a.std(ddof=1))
    if sd == 0.0 or not math.isfinite(sd):
        return mean, mean, mean, (1.0 if mean == 0.0 else 0.0)
    se = sd / math.sqrt(a.size)
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy import stats

    q = float(stats.t.ppf(1.0 - alpha / 2.0, a.size - 1))
    t = mean / se
    p = float(2.0 * stats.t.sf(abs(t), a.size - 1))
    return mean, mean - q * se, mean + q * se, p


def reduction_pct(condition: float, baseline: float) -> float:
    """One participant's reduction, % (NaN when the baseline is not positive)."""
    if not (math.isfinite(condition) and math.isfinite(baseline)) or baseline <= 0.0:
        return math.nan
    return 100.0 * (1.0 - condition / baseline)


def reductions(rows: Sequence[OutcomeRow], baseline: str,
               alpha: float = 0.05) -> list[Reduction]:
    """Every other condition against `baseline`, per channel (channels then conditions
    in order of first appearance). A participant counts where both values are finite
    and the baseline is positive. Holm's correction runs over all rows returned."""
    channels, conditions, values = _table(rows)
    if baseline not in conditions:
        raise ValueError(f"baseline {baseline!r} has no outcome rows "
                         f"(conditions present: {', '.join(conditions) or 'none'})")
    pending: list[tuple[str, str, int, float, float, float, float]] = []
    for ch in channels:
        base = values.get((ch, baseline), {})
        for cond in conditions:
            if cond == baseline:
                continue
            cell = values.get((ch, cond))
            if cell is None:
                continue
            red = [reduction_pct(v, base[p]) for p, v in cell.items() if p in base]
            red = [r for r in red if math.isfinite(r)]
            mean, lo, hi, p = mean_t_interval(red, alpha)
            pending.append((ch, cond, len(red), mean, lo, hi, p))
    adjusted = holm([row[6] for row in pending])
    test = (f"{REDUCTION_TEST}; {round(100 * (1 - alpha))} % t interval; Holm over "
            f"{sum(math.isfinite(p) for p in adjusted)} channel x condition comparisons")
    return [Reduction(ch, cond, baseline, n, mean, lo, hi, p, ph, test)
            for (ch, cond, n, mean, lo, hi, p), ph in zip(pending, adjusted, strict=True)]


def friedman(x: FloatArray) -> tuple[float, float]:
    """Friedman chi-square statistic and p-value of `x` (rows: participants, columns:
    conditions), mid-ranks for ties and the tie correction of the statistic; every
    row all-tied gives 0 and p = 1. Works for two conditions too (scipy's needs 3)."""
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy import stats

    n, k = x.shape
    ranks = np.apply_along_axis(stats.rankdata, 1, x)
    r = ranks.sum(axis=0)
    ties = 0.0
    for row in x:
        _, counts = np.unique(row, return_counts=True)
        ties += float(np.sum(counts.astype(np.float64) ** 3 - counts))
    denom = 1.0 - ties / (n * (k ** 3 - k))
    if denom <= 1e-12:
        return 0.0, 1.0
    q = (12.0 / (n * k * (k + 1)) * float(np.sum(r * r)) - 3.0 * n * (k + 1)) / denom
    q = max(q, 0.0)
    return q, float(stats.chi2.sf(q, k - 1))


def repeated_measures(rows: Sequence[OutcomeRow],
                      conditions: Sequence[str] | None = None) -> list[RepeatedMeasures]:
    """Friedman test across `conditions` (default: every condition, in order of first
    appearance) per channel, over the participants with a finite value in all of
    them. Fewer than two participants or conditions: NaN statistic and p."""
    channels, present, values = _table(rows)
    conds = tuple(conditions) if conditions is not None else tuple(present)
    out: list[RepeatedMeasures] = []
    for ch in channels:
        cells = [values.get((ch, c), {}) for c in conds]
        people = sorted(set.intersection(*(set(c) for c in cells))) if cells else []
        people = [p for p in people if all(math.isfinite(c[p]) for c in cells)]
        k = len(conds)
        if len(people) < 2 or k < 2:
            out.append(RepeatedMeasures(ch, conds, len(people), REPEATED_TEST,
                                        math.nan, max(k - 1, 0), math.nan))
            continue
        x = np.array([[c[p] for c in cells] for p in people], dtype=np.float64)
        q, p = friedman(x)
        out.append(RepeatedMeasures(ch, conds, len(people), REPEATED_TEST, q, k - 1, p))
    return out
