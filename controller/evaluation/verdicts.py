"""How a virtual number is compared with the paper's: the interval over seeds and the
verdict rule.

A replication runs the protocol with several seeds; each seed gives one value per
measure (a mean over that seed's virtual participants). The seeds are independent
repetitions of the same study, so the interval is the **Student t 95 % confidence
interval of the mean over seeds**: `mean +- t(0.975, n - 1) * sd / sqrt(n)`. With five
seeds that is `+- 2.78 sd / sqrt(5)`. A t interval rather than a bootstrap: with five
values a bootstrap interval is too narrow (it cannot reach beyond the observed values).

The verdict rule, one per kind of claim:

- **difference** (a cell of the paper's tables, or a number derived from them, with the
  paper's per-participant values): the difference `virtual - paper`, with the standard
  error of both means (Welch, `controller.evaluation.equivalence`), against an
  equivalence margin stated per claim: *equivalent* if the TOST shows it inside the
  margin (the 90 % Welch interval lies inside `(-margin, +margin)`), *differs* if the
  whole 95 % Welch interval lies beyond the margin on one side (the difference is
  shown to be larger than the margin), *inconclusive* otherwise. The two are
  exclusive (equivalence needs `|d| < margin`), and because "differs" asks for the
  whole interval beyond the margin, more seeds with the same mean can never turn an
  equivalent claim into a differing one.
- **value** (the paper states a number without per-participant values): *reproduced*
  if the paper's number lies inside the interval, *differs* otherwise. A zero-width
  interval (every seed gave the same value) contains only that value.
- **ordinal** (the paper states a direction, "more", "higher", "never reaches"):
  *reproduced* if the whole interval lies on the claimed side of the threshold (for a
  difference, the same sign as the paper's), *differs* otherwise, which includes an
  interval that straddles the threshold (the direction is not shown).
- **check** (a deterministic property of the method, the same for every seed: a
  closed-form number, an identity): *reproduced* if it holds within the stated
  tolerance, *differs* otherwise.
- **not simulated**: the virtual study has nothing to compare (questionnaires).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from controller.evaluation.equivalence import Difference

#: Confidence level of every interval.
CONFIDENCE = 0.95


class Verdict(enum.StrEnum):
    """The outcome of one claim."""

    REPRODUCED = "reproduced"
    EQUIVALENT = "equivalent"
    DIFFERS = "differs"
    INCONCLUSIVE = "inconclusive"
    NOT_SIMULATED = "not simulated"


@dataclass(frozen=True, slots=True)
class Interval:
    """Mean over seeds, its 95 % t interval and the spread (SD) of the seeds."""

    n: int
    mean: float
    low: float
    high: float
    sd: float

    def contains(self, x: float) -> bool:
        """`low <= x <= high` (with a relative tolerance of 1e-9 for rounding)."""
        tol = 1e-9 * max(1.0, abs(x))
        return self.low - tol <= x <= self.high + tol

    def text(self, fmt: str = ".2f") -> str:
        """"m [lo, hi]" (or "m" alone when there is one value)."""
        if not math.isfinite(self.mean):
            return "n/a"
        if self.n < 2:
            return format(self.mean, fmt)
        return f"{self.mean:{fmt}} [{self.low:{fmt}}, {self.high:{fmt}}]"


def t_interval(values: Sequence[float] | np.ndarray) -> Interval:
    """The 95 % Student t interval of the mean of the finite `values`.

    One value gives an interval of zero width with n = 1 (no spread is known); none
    gives NaN.
    """
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return Interval(0, math.nan, math.nan, math.nan, math.nan)
    mean = float(x.mean())
    if n == 1:
        return Interval(1, mean, mean, mean, math.nan)
    sd = float(x.std(ddof=1))
    half = float(stats.t.ppf(0.5 + CONFIDENCE / 2.0, n - 1)) * sd / math.sqrt(n)
    return Interval(n, mean, mean - half, mean + half, sd)


def value_verdict(paper: float, interval: Interval) -> Verdict:
    """A stated number: reproduced if it lies inside the interval."""
    if interval.n == 0:
        return Verdict.DIFFERS
    return Verdict.REPRODUCED if interval.contains(paper) else Verdict.DIFFERS


def ordinal_verdict(interval: Interval, direction: int, threshold: float = 0.0) -> Verdict:
    """A stated direction: reproduced if the whole interval is above the threshold
    (`direction` +1) or below it (-1)."""
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction}")
    if interval.n == 0 or not math.isfinite(interval.mean):
        return Verdict.DIFFERS
    ok = interval.low > threshold if direction > 0 else interval.high < threshold
    return Verdict.REPRODUCED if ok else Verdict.DIFFERS


def check_verdict(value: float, expected: float, tolerance: float) -> Verdict:
    """A deterministic property: reproduced if `|value - expected| <= tolerance`."""
    if not math.isfinite(value):
        return Verdict.DIFFERS
    return Verdict.REPRODUCED if abs(value - expected) <= tolerance else Verdict.DIFFERS


def difference_verdict(d: Difference) -> Verdict:
    """A table claim judged on `virtual - paper` with both errors: equivalent (TOST
    inside the margin), differs (the whole 95 % interval beyond it), else inconclusive."""
    if d.equivalent:
        return Verdict.EQUIVALENT
    if d.beyond_margin:
        return Verdict.DIFFERS
    return Verdict.INCONCLUSIVE
