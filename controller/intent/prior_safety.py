"""Which priors can never make the UMC lock where equal priors would not, and a projection
onto them.

The decision. With likelihoods `p_c` (`p_other = prod_j (1 - p_j)`) and priors `pi`, the
UMC locks when some lock action `a` has `EU(a) > EU(no lock)`. Writing
`d_c(a) = U(a, c, n_c) - U(no lock, c, n_c)` and `x_c(a) = p_c d_c(a)`,

    EU_pi(a) - EU_pi(no lock) = sum_c pi_c x_c(a) / sum_c pi_c p_c.

The denominator is positive, so the sign is that of `sum_c pi_c x_c(a)`.

Roles. From the utility table, each category is classed by the signs its `d_c(a, n)`
can take over every lock action and progress sample: FAVOURS_LOCK (never negative),
OPPOSES_LOCK (never positive), NEUTRAL (always zero) or MIXED. Models are classed over
all 101 samples (more than the online half can reach, so the classing is conservative);
`other` at `n = 0`, the only sample the decision reads. With the project's default
utilities (`other_rule="worst-difference"`) `other` opposes locking and squat favours it;
both stoops are mixed (locking the supporting side helps, the other side hurts).

The safe set. `pi` is safe if there is a `lambda >= 0` with `pi_c = lambda` for MIXED
categories, `pi_c <= lambda` for FAVOURS_LOCK and `pi_c >= lambda` for OPPOSES_LOCK
(NEUTRAL free), every `pi_c >= floor_c`, and `sum pi = 1`.

Theorem. For a safe `pi`, every observation on which equal priors do not lock is one
on which `pi` does not lock. Proof: `pi = lambda 1 + y` with `y_c <= 0` where
`x_c(a) >= 0` always and `y_c >= 0` where `x_c(a) <= 0` always (`y_c = 0` where signs
vary, anything where `x_c = 0`), so `sum_c pi_c x_c(a) = lambda sum_c x_c(a) +
sum_c y_c x_c(a) <= lambda sum_c x_c(a) <= 0` when equal priors do not lock
(`sum_c x_c(a) <= 0` for every `a`). Ties go to no lock in both. So, on any recording,
the ticks on which `pi` decides a lock are a subset of those on which equal priors do.

Converse (why the set is not larger): the sign pattern is free within each role (any
`p_c` in [0, 1], any progress), and by Farkas' lemma the priors that keep
`sum pi_c x_c <= 0` on the whole cone `{x : sum x_c <= 0, x_c in its role's signs}` are
exactly the safe set. In particular "the lock classes' total never exceeds 3/4 and other
never drops below 1/4" is not enough: raising one stoop above the other flips
observations where that stoop's gain balances the other's cost.

Corollary. When `other` opposes locking and no category is NEUTRAL, `other` is the
largest prior of a safe set, so it is never below its equal share 1/4.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from controller.decision.expected_utility import lock_margin
from controller.tick_record import CATEGORY_NAMES

FloatArray = npt.NDArray[np.float64]

N_CATEGORIES = len(CATEGORY_NAMES)
#: Default floor of every category: a fifth of the equal prior. A stated choice: it keeps
#: each lift recognisable (a class at its floor against an accepted rival at the largest
#: safe prior, 0.3, still gets a sixth of that rival's posterior for the same
#: likelihood) and is far below 1/4, so the equal priors are always safe. It is also the
#: least floor allowed: a floor below it (1e-12, say) would let a motion all but vanish.
DEFAULT_FLOOR = 0.05
_BISECT = 200


class ClassRole(enum.StrEnum):
    """How a category's utilities push the lock decision."""

    FAVOURS_LOCK = "favours_lock"
    OPPOSES_LOCK = "opposes_lock"
    MIXED = "mixed"
    NEUTRAL = "neutral"


def class_roles(table: npt.ArrayLike) -> tuple[ClassRole, ...]:
    """Each category's role from a `(4 actions, 4 categories, 101)` utility table."""
    t = np.asarray(table, dtype=np.float64)
    if t.ndim != 3 or t.shape[:2] != (4, N_CATEGORIES):
        raise ValueError(f"utility table must have shape (4, 4, n), got {t.shape}")
    if not np.isfinite(t).all():
        raise ValueError("utility table contains NaN or inf")
    d = t[1:] - t[:1]  # lock actions minus no lock
    roles = []
    for c in range(N_CATEGORIES):
        dc = d[:, c, :1] if c == N_CATEGORIES - 1 else d[:, c, :]
        pos, neg = bool((dc > 0).any()), bool((dc < 0).any())
        roles.append(ClassRole.MIXED if pos and neg else ClassRole.FAVOURS_LOCK if pos
                     else ClassRole.OPPOSES_LOCK if neg else ClassRole.NEUTRAL)
    return tuple(roles)


@dataclass(frozen=True)
class PriorBounds:
    """The safe set of priors for one utility table (see the module docstring)."""

    roles: tuple[ClassRole, ...]
    floors: tuple[float, ...] = (DEFAULT_FLOOR,) * N_CATEGORIES

    def __post_init__(self) -> None:
        if len(self.roles) != N_CATEGORIES or len(self.floors) != N_CATEGORIES:
            raise ValueError(f"roles and floors need {N_CATEGORIES} entries each")
        object.__setattr__(self, "roles", tuple(ClassRole(r) for r in self.roles))
        fl = tuple(float(f) for f in self.floors)
        if not all(DEFAULT_FLOOR <= f <= 0.25 for f in fl):
            raise ValueError(f"floors must lie in [{DEFAULT_FLOOR:g}, 0.25] (every motion "
                             f"recognisable, equal priors safe), got {fl}")
        object.__setattr__(self, "floors", fl)

    @classmethod
    def for_table(cls, table: npt.ArrayLike,
                  floors: Sequence[float] = (DEFAULT_FLOOR,) * N_CATEGORIES) -> PriorBounds:
        """The bounds of a utility table (`UtilitySet.table.values`)."""
        return cls(class_roles(table), tuple(floors))

    def _box(self, lam: float) -> tuple[FloatArray, FloatArray]:
        lo = np.empty(N_CATEGORIES)
        hi = np.empty(N_CATEGORIES)
        for c, (r, f) in enumerate(zip(self.roles, self.floors, strict=True)):
            if r is ClassRole.MIXED:
                lo[c], hi[c] = lam, lam
            elif r is ClassRole.FAVOURS_LOCK:
                lo[c], hi[c] = f, lam
            elif r is ClassRole.OPPOSES_LOCK:
                lo[c], hi[c] = max(f, lam), 1.0
            else:
                lo[c], hi[c] = f, 1.0
        return lo, hi

    def _feasible(self, lam: float) -> bool:
        lo, hi = self._box(lam)
        return bool((lo <= hi).all() and lo.sum() <= 1.0 <= hi.sum())

    def _lambda_range(self) -> tuple[float, float]:
        """The interval of `lambda` with a feasible box: `lambda` at least every floor of
        a category bounded by it from above, the box's upper ends summing to at least 1
        and its lower ends to at most 1 (both sums grow with lambda)."""
        a = max([f for r, f in zip(self.roles, self.floors, strict=True)
                 if r in (ClassRole.MIXED, ClassRole.FAVOURS_LOCK)], default=0.0)

        def hi_ok(lam: float) -> bool:
            return bool(self._box(lam)[1].sum() >= 1.0)

        def lo_ok(lam: float) -> bool:
            return bool(self._box(lam)[0].sum() <= 1.0)

        if not hi_ok(a):
            a = _edge(lambda lam: not hi_ok(lam), a, 1.0, toward_outside=True)
        b = 1.0 if lo_ok(1.0) else _edge(lo_ok, a, 1.0)
        if a > b or not lo_ok(a):
            raise ValueError(f"no priors satisfy floors {self.floors} with roles "
                             f"{[r.value for r in self.roles]}")
        return a, b

    def _fit_box(self, est: FloatArray, lam: float) -> FloatArray:
        """Euclidean projection of `est` onto the box of `lam` within `sum = 1`."""
        lo, hi = self._box(lam)
        a, b = -1.0 - float(est.max()), 1.0 + float(-est.min())
        for _ in range(_BISECT):
            mid = 0.5 * (a + b)
            if float(np.clip(est + mid, lo, hi).sum()) < 1.0:
                a = mid
            else:
                b = mid
            if b - a < 1e-17:
                break
        return np.asarray(np.clip(est + 0.5 * (a + b), lo, hi), dtype=np.float64)

    def project(self, estimate: npt.ArrayLike) -> FloatArray:
        """The safe priors closest (Euclidean) to `estimate`; safe priors map to themselves.

        The squared distance to the box of each `lambda` is convex in `lambda` (a
        partial minimisation of a jointly convex problem), so a golden-section search
        over the feasible `lambda` finds the optimum. Relations to `lambda` hold exactly
        (clipping to `lambda` copies it); the sum is 1 to rounding.
        """
        est = np.asarray(estimate, dtype=np.float64)
        if est.shape != (N_CATEGORIES,) or not np.isfinite(est).all():
            raise ValueError(f"an estimate needs {N_CATEGORIES} finite values, got {est!r}")
        if self.contains(est):
            return est.copy()
        a, b = self._lambda_range()

        def cost(lam: float) -> float:
            return float(((self._fit_box(est, lam) - est) ** 2).sum())

        g = (np.sqrt(5.0) - 1.0) / 2.0
        x1, x2 = b - g * (b - a), a + g * (b - a)
        f1, f2 = cost(x1), cost(x2)
        for _ in range(120):
            if f1 <= f2:
                b, x2, f2 = x2, x1, f1
                x1 = b - g * (b - a)
                f1 = cost(x1)
            else:
                a, x1, f1 = x1, x2, f2
                x2 = a + g * (b - a)
                f2 = cost(x2)
        lam = 0.5 * (a + b)
        return self._fit_box(est, lam)

    def contains(self, priors: npt.ArrayLike, sum_tol: float = 1e-9) -> bool:
        """Whether `priors` are safe: relations and floors exactly, the sum within
        `sum_tol` (the tolerance of `ControllerConfig`)."""
        return self.violation(priors, sum_tol) is None

    def violation(self, priors: npt.ArrayLike, sum_tol: float = 1e-9,
                  floors: bool = True) -> str | None:
        """Why `priors` are not safe, in words, or None if they are. Without `floors`
        only the theorem's relations are checked (the floors keep classes recognisable;
        the lock-rate theorem does not need them)."""
        p = np.asarray(priors, dtype=np.float64)
        if p.shape != (N_CATEGORIES,) or not np.isfinite(p).all():
            return f"need {N_CATEGORIES} finite values"
        if abs(float(p.sum()) - 1.0) > sum_tol:
            return f"they sum to {float(p.sum())!r}, not 1"
        names = CATEGORY_NAMES
        if (p < 0).any():
            return f"{names[int(np.argmax(p < 0))]} is negative"
        for c, f in enumerate(self.floors):
            if floors and p[c] < f:
                return f"{names[c]} is {p[c]:.4g}, below its floor {f:g}"
        mixed = [c for c, r in enumerate(self.roles) if r is ClassRole.MIXED]
        fav = [c for c, r in enumerate(self.roles) if r is ClassRole.FAVOURS_LOCK]
        opp = [c for c, r in enumerate(self.roles) if r is ClassRole.OPPOSES_LOCK]
        if mixed and any(p[c] != p[mixed[0]] for c in mixed):
            return (f"{', '.join(names[c] for c in mixed)} push the decision both ways and "
                    f"must share one prior, got {[float(p[c]) for c in mixed]}")
        lam_lo = max([float(p[c]) for c in fav + mixed], default=0.0)
        lam_hi = min([float(p[c]) for c in opp + mixed], default=1.0)
        if lam_lo > lam_hi:
            return ("a category that favours locking (or pushes both ways) has a larger "
                    "prior than one that opposes it: "
                    + ", ".join(f"{names[c]}={float(p[c]):.4g}" for c in fav + mixed + opp))
        return None


def _edge(ok: Callable[[float], bool], inside: float, outside: float,
          toward_outside: bool = False) -> float:
    """Bisect the boundary of a monotone predicate, `ok(inside)` true and `ok(outside)`
    false; the last point where it holds, or with `toward_outside` the first where it
    fails."""
    for _ in range(80):
        mid = 0.5 * (inside + outside)
        if ok(mid):
            inside = mid
        else:
            outside = mid
    return outside if toward_outside else inside


def lock_decided(table: FloatArray, s_curr: FloatArray, p_obs: FloatArray,
                 priors: npt.ArrayLike) -> npt.NDArray[np.bool_]:
    """Whether the UMC decides a lock, for many evaluations at once.

    Args:
        table: `(4, 4, 101)` utilities.
        s_curr: `(m, 3)` progress per model (NaN where rejected).
        p_obs: `(m, 3)` `P(obs | model_j)` (0 where rejected).
        priors: `(4,)` priors.

    The same rules as `expected_utility` and `posteriors` (ties to no lock, other read
    at `n = 0`, a lock under unequal priors only by `lock_margin`), vectorised for
    property tests and for re-deciding recorded evaluations under other priors.
    """
    pr = np.asarray(priors, dtype=np.float64)
    p = np.asarray(p_obs, dtype=np.float64)
    s = np.asarray(s_curr, dtype=np.float64)
    m = p.shape[0]
    other = np.prod(1.0 - p, axis=1)
    w = np.concatenate([p * pr[:3], (other * pr[3])[:, None]], axis=1)
    total = w.sum(axis=1)
    post = np.where(total[:, None] > 0, w / np.where(total > 0, total, 1.0)[:, None],
                    np.array([0.0, 0.0, 0.0, 1.0]))
    n_last = table.shape[2] - 1
    idx = np.clip(np.floor(np.nan_to_num(s, nan=0.0) * n_last + 0.5), 0, n_last).astype(int)
    eu = post[:, 3:4] * table[:, 3, 0][None, :]
    for j in range(3):
        u = table[:, j, :][:, idx[:, j]].T  # (m, 4)
        eu = eu + np.where(post[:, j:j + 1] != 0.0, post[:, j:j + 1] * u, 0.0)
    margin = lock_margin(pr)
    best = np.zeros(m, dtype=int)
    for a in range(1, 4):
        wins = eu[:, a] > eu[np.arange(m), best]
        if margin:
            size = post[:, 3] * (abs(table[a, 3, 0]) + abs(table[0, 3, 0]))
            for j in range(3):
                u = np.abs(table[a, j, idx[:, j]]) + np.abs(table[0, j, idx[:, j]])
                size = size + np.where(post[:, j] != 0.0, post[:, j] * u, 0.0)
            wins &= eu[:, a] - eu[:, 0] > margin * size
        best = np.where(wins, a, best)
    return np.asarray(best > 0)
