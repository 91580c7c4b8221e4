"""The difference between the virtual study and the paper, with both sampling errors:
Welch's interval and the two one-sided tests (TOST) of equivalence.

The paper's number for a table cell is the mean of its few participants, not an exact
value, and the virtual number is the mean of a few seeds; judging one against the
other as if the paper's were exact lets the verdict depend on how many seeds were run
(more seeds shrink only the virtual interval). Here both means carry their standard
error:

- **Welch interval** of `mean(virtual) - mean(paper)`: `d +- t(1 - a/2, df) * se`,
  `se = sqrt(s_v^2 / n_v + s_p^2 / n_p)` with the Welch-Satterthwaite degrees of freedom
  `df = se^4 / ((s_v^2/n_v)^2 / (n_v - 1) + (s_p^2/n_p)^2 / (n_p - 1))`. Unequal
  variances are the rule here: the virtual units are seed means, the paper's are
  single participants.
- **TOST** (Schuirmann 1987) against a margin `m`: two one-sided t tests of
  `H0: delta <= -m` and `H0: delta >= +m` with the same `se` and `df`; its p value is
  the larger of the two. `p < alpha` is the same as the `1 - 2 alpha` (90 %) Welch
  interval lying inside `(-m, +m)`.

When neither sample varies (`se == 0`) the difference is known exactly: its interval
has zero width and the TOST p value is 0 inside the margin and 1 outside it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

#: Level of the reported interval, and the TOST's alpha (its interval is 1 - 2 alpha).
CONFIDENCE = 0.95
ALPHA = 0.05


def _finite(values: Sequence[float] | np.ndarray) -> np.ndarray:
    x = np.asarray(values, dtype=np.float64)
    return x[np.isfinite(x)]


@dataclass(frozen=True, slots=True)
class Difference:
    """`virtual - paper` with both sampling errors (see the module docstring).

    Attributes:
        n_virtual, n_paper: sample sizes (finite values only).
        mean_virtual, mean_paper: the two means.
        se_virtual, se_paper: their standard errors (`sd / sqrt(n)`).
        diff: `mean_virtual - mean_paper`.
        se: standard error of the difference.
        df: Welch-Satterthwaite degrees of freedom (inf when `se == 0`).
        low, high: the 95 % Welch interval of the difference.
        margin: the equivalence margin (NaN when none was given).
        tost_p: TOST p value against `margin` (NaN without a margin).
    """

    n_virtual: int
    n_paper: int
    mean_virtual: float
    mean_paper: float
    se_virtual: float
    se_paper: float
    diff: float
    se: float
    df: float
    low: float
    high: float
    margin: float = math.nan
    tost_p: float = math.nan

    def interval(self, confidence: float = CONFIDENCE) -> tuple[float, float]:
        """The Welch interval of the difference at another level (the TOST's is 0.90)."""
        half = _t_quantile(0.5 + confidence / 2.0, self.df) * self.se
        return self.diff - half, self.diff + half

    @property
    def equivalent(self) -> bool:
        """TOST at `ALPHA`: the difference is shown to lie inside `(-margin, +margin)`."""
        return math.isfinite(self.tost_p) and self.tost_p < ALPHA

    @property
    def beyond_margin(self) -> bool:
        """The whole 95 % interval lies outside `[-margin, +margin]` on one side: the
        difference is shown to be larger than the margin."""
        if not math.isfinite(self.margin):
            return False
        return self.low > self.margin or self.high < -self.margin

    def text(self, fmt: str = ".3g") -> str:
        """'d [lo, hi]' of the difference."""
        return f"{self.diff:{fmt}} [{self.low:{fmt}}, {self.high:{fmt}}]"


def _t_quantile(q: float, df: float) -> float:
    return float(stats.norm.ppf(q)) if math.isinf(df) else float(stats.t.ppf(q, df))


def welch(virtual: Sequence[float] | np.ndarray, paper: Sequence[float] | np.ndarray,
          margin: float = math.nan) -> Difference:
    """Welch's 95 % interval of `mean(virtual) - mean(paper)`, and the TOST p value
    against `margin` when one is given.

    Raises:
        ValueError: fewer than two finite values on either side (no spread is known),
            or a negative margin.
    """
    v, p = _finite(virtual), _finite(paper)
    if v.size < 2 or p.size < 2:
        raise ValueError(f"welch: need at least two finite values on each side, got "
                         f"{v.size} virtual and {p.size} paper")
    if margin < 0:
        raise ValueError(f"welch: the margin must be >= 0, got {margin}")
    a = float(v.var(ddof=1)) / v.size
    b = float(p.var(ddof=1)) / p.size
    se = math.sqrt(a + b)
    denom = a * a / (v.size - 1) + b * b / (p.size - 1)
    df = (a + b) ** 2 / denom if denom > 0 else math.inf
    diff = float(v.mean()) - float(p.mean())
    half = _t_quantile(0.5 + CONFIDENCE / 2.0, df) * se
    return Difference(int(v.size), int(p.size), float(v.mean()), float(p.mean()),
                      math.sqrt(a), math.sqrt(b), diff, se, df, diff - half, diff + half,
                      margin, tost_p(diff, se, df, margin))


def tost_p(diff: float, se: float, df: float, margin: float) -> float:
    """The TOST p value of an estimated difference `diff` with standard error `se` and
    `df` degrees of freedom against the margin: the larger of the p values of
    `H0: delta <= -margin` and `H0: delta >= +margin` (NaN without a margin)."""
    if not (math.isfinite(margin) and math.isfinite(diff)):
        return math.nan
    if se == 0.0:
        return 0.0 if abs(diff) < margin else 1.0
    dist = stats.norm if math.isinf(df) else stats.t(df)
    p_low = float(dist.sf((diff + margin) / se))   # against delta <= -margin
    p_high = float(dist.cdf((diff - margin) / se))  # against delta >= +margin
    return max(p_low, p_high)
