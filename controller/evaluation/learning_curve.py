"""A wearer's progress over long-use sessions: per-session metrics, their 95 % intervals,
and the trend of each over sessions (a learning curve).

The paper's discussion expects wearers to learn "how to reliably trigger locking" over
a longer time horizon; this module turns what each session of use gave (its evaluated
lifts, its walking and stair bouts, how long the controller ran) into six numbers per
session and a least-squares slope per session for each. Pure NumPy/SciPy: the backend
gathers the sessions (`backend.analysis.wearer_progress`), this module only counts.

The metrics, per session:

- **lifts per hour**: every lift the session held (confirmed, unconfirmed and those cut
  by the session's start or end) over the hours the controller ran; 95 % interval:
  exact Poisson (Garwood 1936) on the count.
- **recognition rate**: confirmed lifts whose correct posterior reached 0.5 in their
  first half (`controller.evaluation.metrics`), over the confirmed lifts; None for a
  controller without intent estimation. Interval: Wilson score.
- **lock rate**: confirmed lifts with a correct lock decision by the paper's counting
  rule (`LiftOutcome.decision`), over the confirmed lifts. Interval: Wilson score.
- **time to lock**: mean onset-to-correct-lock time (`LiftOutcome.correct_lock_s`) of
  the confirmed lifts that locked correctly; interval: Student t on the mean.
- **false positives per hour of walking** and **of stairs**: the paper's false
  positive lock signals (`FalsePositives.signals`) summed over the session's walking
  (stair-walking) bouts, over those bouts' hours. Interval: exact Poisson.

Unconfirmed lifts (a lift seen but its motion not known) count in lifts per hour
only: a rate over lifts whose correct action is unknown would be a guess.

The trend of a metric is the ordinary least-squares slope of its per-session values
against the session's number (1, 2, ... in time order), unweighted, over the sessions
where the metric has a value, with a 95 % interval from Student's t on `n - 2` degrees
of freedom (none below three sessions). Unweighted because the question is whether the
wearer's sessions improve, not whether the longest one dominates; each point's own
interval shows how much it can be trusted.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from scipy import stats

from controller.evaluation.metrics import DecisionOutcome, FalsePositives, LiftOutcome

Metric = Literal["lifts_per_hour", "recognition_rate", "lock_rate", "time_to_lock_s",
                 "fp_per_hour_walking", "fp_per_hour_stairs"]
#: Every metric of a session, in the order pages show them.
METRICS: tuple[Metric, ...] = ("lifts_per_hour", "recognition_rate", "lock_rate",
                               "time_to_lock_s", "fp_per_hour_walking",
                               "fp_per_hour_stairs")
#: The level of every interval of this module.
LEVEL = 0.95
_SECONDS_PER_HOUR = 3600.0


@dataclass(frozen=True)
class SessionUse:
    """What one long-use session gave, as counts and exposure.

    Attributes:
        hours: device time the controller ran in the session, in hours.
        lifts: every lift of the session (confirmed, unconfirmed and incomplete).
        confirmed: lifts whose motion is known and which were evaluated.
        recognised: confirmed lifts recognised; None if the controller estimates no
            intent.
        correct_locks: confirmed lifts with a correct lock decision (paper's rule).
        lock_times_s: onset to correct lock of each confirmed lift that locked (s).
        walking_hours, walking_fp: hours of walking bouts and false positive signals
            in them; `stairs_*` the same for stair-walking bouts.
    """

    hours: float
    lifts: int = 0
    confirmed: int = 0
    recognised: int | None = 0
    correct_locks: int = 0
    lock_times_s: tuple[float, ...] = ()
    walking_hours: float = 0.0
    walking_fp: int = 0
    stairs_hours: float = 0.0
    stairs_fp: int = 0

    def __post_init__(self) -> None:
        for name in ("hours", "walking_hours", "stairs_hours"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {v!r}")
        for name in ("lifts", "confirmed", "correct_locks", "walking_fp", "stairs_fp"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.confirmed > self.lifts:
            raise ValueError(f"confirmed ({self.confirmed}) exceeds lifts ({self.lifts})")
        if self.recognised is not None and not 0 <= self.recognised <= self.confirmed:
            raise ValueError(f"recognised must be in 0..{self.confirmed}")
        if not 0 <= self.correct_locks <= self.confirmed:
            raise ValueError(f"correct_locks must be in 0..{self.confirmed}")


def session_use(hours: float, outcomes: Sequence[LiftOutcome],
                false_positives: Sequence[FalsePositives], unconfirmed: int = 0,
                incomplete: int = 0) -> SessionUse:
    """A session's counts from its evaluated lifts and gait bouts (all its trials').

    Args:
        hours: device time the controller ran, in hours.
        outcomes: the confirmed lifts, evaluated (`evaluate_lifts`).
        false_positives: per walking or stair-walking bout (`count_false_positives`).
        unconfirmed: lifts seen whose motion is not known (count in lifts per hour).
        incomplete: lifts cut by the start or end of a trial (count in lifts per hour).
    """
    rec = [o.recognised for o in outcomes]
    intent = not outcomes or any(r is not None for r in rec)
    times = tuple(float(o.correct_lock_s) for o in outcomes
                  if o.decision == DecisionOutcome.CORRECT and math.isfinite(o.correct_lock_s))
    walk = [f for f in false_positives if f.trial.kind == "walking"]
    stairs = [f for f in false_positives if f.trial.kind == "stair_walking"]
    return SessionUse(
        hours=hours, lifts=len(outcomes) + unconfirmed + incomplete, confirmed=len(outcomes),
        recognised=sum(1 for r in rec if r) if intent else None,
        correct_locks=sum(1 for o in outcomes if o.decision == DecisionOutcome.CORRECT),
        lock_times_s=times,
        walking_hours=sum(f.duration_s for f in walk) / _SECONDS_PER_HOUR,
        walking_fp=sum(f.signals for f in walk),
        stairs_hours=sum(f.duration_s for f in stairs) / _SECONDS_PER_HOUR,
        stairs_fp=sum(f.signals for f in stairs))


# --------------------------------------------------------------------------- intervals


def wilson(k: int, n: int, level: float = LEVEL) -> tuple[float, float]:
    """Wilson score interval of a proportion `k / n` (NaN, NaN for n = 0): unlike the
    normal approximation it stays inside [0, 1] and is not empty at 0 or n."""
    if n <= 0:
        return math.nan, math.nan
    if not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n, got k={k}, n={n}")
    z = float(stats.norm.ppf(0.5 + level / 2))
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    # At k = 0 (k = n) the limit is exactly 0 (1); rounding would leave it beside.
    low = 0.0 if k == 0 else max(0.0, mid - half)
    high = 1.0 if k == n else min(1.0, mid + half)
    return low, high


def poisson_rate(k: int, exposure: float, level: float = LEVEL) -> tuple[float, float]:
    """Exact (Garwood) interval of a Poisson rate `k / exposure` (NaN, NaN without
    exposure): chi-square quantiles of 2k and 2k + 2 degrees of freedom."""
    if not exposure > 0:
        return math.nan, math.nan
    if k < 0:
        raise ValueError(f"a count is >= 0, got {k}")
    a = 1 - level
    low = 0.0 if k == 0 else float(stats.chi2.ppf(a / 2, 2 * k)) / 2
    high = float(stats.chi2.ppf(1 - a / 2, 2 * k + 2)) / 2
    return low / exposure, high / exposure


def mean_interval(values: Sequence[float], level: float = LEVEL) -> tuple[float, float, float]:
    """Mean and its Student t interval (the interval is NaN below two values)."""
    x = np.asarray(values, dtype=np.float64)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    m = float(x.mean())
    if x.size < 2:
        return m, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + level / 2, x.size - 1)) * float(x.std(ddof=1)) / math.sqrt(
        x.size)
    return m, m - half, m + half


# --------------------------------------------------------------------------- points


@dataclass(frozen=True)
class Point:
    """One session's value of a metric with its 95 % interval (NaN: no value).

    `n` is what the value rests on: lifts for rates and times, hours for per-hour
    metrics."""

    session: int
    value: float
    low: float
    high: float
    n: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, NaN as None."""
        return {"session": self.session, "value": _num(self.value), "low": _num(self.low),
                "high": _num(self.high), "n": _num(self.n)}


def point(metric: Metric, use: SessionUse, session: int) -> Point:
    """`metric` of one session (numbered `session`) with its interval."""
    nan = math.nan
    if metric == "lifts_per_hour":
        low, high = poisson_rate(use.lifts, use.hours)
        value = use.lifts / use.hours if use.hours > 0 else nan
        return Point(session, value, low, high, use.hours)
    if metric in ("recognition_rate", "lock_rate"):
        k = use.recognised if metric == "recognition_rate" else use.correct_locks
        if k is None or use.confirmed == 0:
            return Point(session, nan, nan, nan, use.confirmed)
        low, high = wilson(k, use.confirmed)
        return Point(session, k / use.confirmed, low, high, use.confirmed)
    if metric == "time_to_lock_s":
        m, low, high = mean_interval(use.lock_times_s)
        return Point(session, m, low, high, len(use.lock_times_s))
    if metric in ("fp_per_hour_walking", "fp_per_hour_stairs"):
        walking = metric == "fp_per_hour_walking"
        k = use.walking_fp if walking else use.stairs_fp
        h = use.walking_hours if walking else use.stairs_hours
        low, high = poisson_rate(k, h)
        return Point(session, k / h if h > 0 else nan, low, high, h)
    raise ValueError(f"unknown metric {metric!r}; choose one of {', '.join(METRICS)}")


# --------------------------------------------------------------------------- trend


@dataclass(frozen=True)
class Trend:
    """Least-squares line of a metric over session numbers: `slope` per session with
    its 95 % interval (NaN below three sessions with a value), `n` sessions used."""

    n: int
    slope: float
    intercept: float
    low: float
    high: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, NaN as None."""
        return {"n": self.n, "slope": _num(self.slope), "intercept": _num(self.intercept),
                "low": _num(self.low), "high": _num(self.high)}


def trend(x: Sequence[float], y: Sequence[float], level: float = LEVEL) -> Trend:
    """Ordinary least-squares slope of `y` on `x` with its Student t interval; pairs
    with a non-finite `y` are left out. The slope is computed on `y - y[0]` (the same
    slope), so a constant series gives exactly 0 whatever its value's rounding."""
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    if xa.shape != ya.shape:
        raise ValueError(f"x and y differ in length ({xa.size} and {ya.size})")
    keep = np.isfinite(ya) & np.isfinite(xa)
    xa, ya = xa[keep], ya[keep]
    n = int(xa.size)
    nan = math.nan
    if n == 0:
        return Trend(0, nan, nan, nan, nan)
    if n == 1:
        return Trend(1, nan, float(ya[0]), nan, nan)
    dy = ya - ya[0]
    dx = xa - xa.mean()
    sxx = float(dx @ dx)
    if sxx == 0.0:
        raise ValueError("x must hold at least two different values")
    slope = float(dx @ (dy - dy.mean())) / sxx
    intercept = float(ya.mean() - slope * xa.mean())
    if n < 3:
        return Trend(n, slope, intercept, nan, nan)
    resid = dy - dy.mean() - slope * dx
    se = math.sqrt(float(resid @ resid) / (n - 2) / sxx)
    half = float(stats.t.ppf(0.5 + level / 2, n - 2)) * se
    return Trend(n, slope, intercept, slope - half, slope + half)


@dataclass(frozen=True)
class Curve:
    """A metric over a wearer's sessions and its trend."""

    metric: Metric
    points: tuple[Point, ...]
    trend: Trend

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, NaN as None."""
        return {"metric": self.metric, "points": [p.to_dict() for p in self.points],
                "trend": self.trend.to_dict()}


def learning_curves(sessions: Sequence[SessionUse]) -> dict[Metric, Curve]:
    """Every metric over `sessions` (in time order, numbered 1, 2, ...) with its trend."""
    out: dict[Metric, Curve] = {}
    for metric in METRICS:
        pts = tuple(point(metric, use, i) for i, use in enumerate(sessions, start=1))
        out[metric] = Curve(metric, pts, trend([p.session for p in pts],
                                               [p.value for p in pts]))
    return out


def _num(v: float) -> float | None:
    return None if math.isnan(v) else float(v)
