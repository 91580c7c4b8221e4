"""Priors learned from a wearer's use: a versioned record and the count-based update.

The paper set the four priors equal "as a first starting point" and expected them to
be updated once usage data exist. This module keeps two things apart:

- the **estimate**: what the wearer's history says (for insight into how they use the
  exoskeleton), and
- the **values**: the estimate projected onto the safe set of the utility table
  (`controller.intent.prior_safety.PriorBounds`), which is all the controller uses.

Count-based update (Dirichlet posterior mean with forgetting). Every confirmed motion
(ground truth in simulation; markers or the lift segmentation in a study) adds 1 to its
category's count after all counts are multiplied by the forgetting factor `gamma`
(per confirmed motion), so a motion `t` confirmations ago weighs `gamma^t`. Then
`estimate_k = (alpha_k + n_k) / (sum alpha + N)` with pseudo-counts `alpha_k`.
Defaults (stated choices): `alpha_k = 2.5` (equal priors worth ten motions, so the first
few lifts move the estimate but do not decide it) and `gamma = 0.99` (a memory of about
`1 / (1 - gamma) = 100` motions: a few weeks of a working day's lifts).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

import numpy as np
import numpy.typing as npt

from controller.intent.posteriors import EQUAL_PRIORS
from controller.intent.prior_safety import ClassRole, PriorBounds
from controller.tick_record import CATEGORY_NAMES

FloatArray = npt.NDArray[np.float64]

FORMAT_NAME = "exostudy.learned_priors"
FORMAT_VERSION = 1
DEFAULT_PSEUDO_COUNT = 2.5
DEFAULT_FORGETTING = 0.99
METHODS = ("equal", "dirichlet", "label-shift-em")


def _floats(name: str, v: object, n: int = len(CATEGORY_NAMES)) -> tuple[float, ...]:
    if not isinstance(v, tuple | list) or len(v) != n:
        raise ValueError(f"{name}: must be {n} numbers ({', '.join(CATEGORY_NAMES)}), got {v!r}")
    out = []
    for x in v:
        if isinstance(x, bool) or not isinstance(x, int | float) or not np.isfinite(x):
            raise ValueError(f"{name}: must be finite numbers, got {v!r}")
        out.append(float(x))
    return tuple(out)


@dataclass(frozen=True)
class LearnedPriors:
    """A versioned set of priors with where it came from.

    Attributes:
        version: label chosen by whoever made it.
        values: the priors the controller uses, in `classes` order (safe by `bounds`).
        estimate: the unbounded estimate from the history (equal to `values` for the
            equal priors).
        method: "equal", "dirichlet" (confirmed motions) or "label-shift-em".
        classes: category order, the model set's models then "other".
        pseudo_counts, counts, forgetting: the Dirichlet update's state (counts are the
            forgotten counts after the last motion).
        floors, roles: the safety bound the values were projected with.
        sources: ids of the motions (lifts, bouts) that fed the estimate, oldest first.
        created: ISO 8601 UTC time.
        meta: anything else (utility set, EM iterations and test, participant).
    """

    version: str
    values: tuple[float, ...]
    estimate: tuple[float, ...]
    method: str = "equal"
    classes: tuple[str, ...] = CATEGORY_NAMES
    pseudo_counts: tuple[float, ...] = (DEFAULT_PSEUDO_COUNT,) * len(CATEGORY_NAMES)
    counts: tuple[float, ...] = (0.0,) * len(CATEGORY_NAMES)
    forgetting: float = DEFAULT_FORGETTING
    floors: tuple[float, ...] = ()
    roles: tuple[str, ...] = ()
    sources: tuple[str, ...] = ()
    created: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if tuple(self.classes) != CATEGORY_NAMES:
            raise ValueError(f"classes: must be {list(CATEGORY_NAMES)} in that order, got "
                             f"{list(self.classes)}")
        object.__setattr__(self, "classes", tuple(self.classes))
        for name in ("values", "estimate", "pseudo_counts", "counts"):
            object.__setattr__(self, name, _floats(name, getattr(self, name)))
        for name in ("values", "estimate"):
            v = getattr(self, name)
            if any(x < 0 or x > 1 for x in v) or abs(sum(v) - 1.0) > 1e-9:
                raise ValueError(f"{name}: must be in [0, 1] and sum to 1, got {list(v)}")
        if any(x <= 0 for x in self.pseudo_counts):
            raise ValueError(f"pseudo_counts: must be positive, got {list(self.pseudo_counts)}")
        if any(x < 0 for x in self.counts):
            raise ValueError(f"counts: must be >= 0, got {list(self.counts)}")
        if not 0.0 < float(self.forgetting) <= 1.0:
            raise ValueError(f"forgetting: must be in (0, 1], got {self.forgetting!r}")
        if self.method not in METHODS:
            raise ValueError(f"method: must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.floors or self.roles:
            problem = self.bounds.violation(self.values)  # ValueError for bad roles/floors
            if problem is not None:
                raise ValueError(f"values: outside their safety bound: {problem}")
        object.__setattr__(self, "sources", tuple(str(s) for s in self.sources))
        object.__setattr__(self, "roles", tuple(str(r) for r in self.roles))

    @property
    def bounds(self) -> PriorBounds:
        """The bound the values satisfy."""
        return PriorBounds(tuple(ClassRole(r) for r in self.roles), self.floors)

    def to_json(self) -> dict[str, Any]:
        """Versioned JSON document."""
        return {"format": FORMAT_NAME, "format_version": FORMAT_VERSION,
                "version": self.version, "method": self.method, "classes": list(self.classes),
                "values": list(self.values), "estimate": list(self.estimate),
                "pseudo_counts": list(self.pseudo_counts), "counts": list(self.counts),
                "forgetting": self.forgetting, "floors": list(self.floors),
                "roles": list(self.roles), "sources": list(self.sources),
                "created": self.created, "meta": self.meta}

    @classmethod
    def from_json(cls, data: Any) -> LearnedPriors:
        """Inverse of `to_json`; refuses other formats and, with `ValueError` naming the
        field, a missing field or one of the wrong type (a stored document may have been
        altered: a caller answers a clear refusal, never a crash)."""
        if not isinstance(data, dict):
            raise ValueError(f"priors: must be a JSON object, got {type(data).__name__}")
        if data.get("format") != FORMAT_NAME:
            raise ValueError(f"not an {FORMAT_NAME} document (format={data.get('format')!r})")
        if data.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"unsupported format_version {data.get('format_version')!r}")
        missing = [k for k in _REQUIRED if k not in data]
        if missing:
            raise ValueError(f"priors document lacks field {missing[0]!r}")
        for name in ("version", "method", "created"):
            v = data.get(name, "")
            if isinstance(v, bool) or not isinstance(v, str | int):
                raise ValueError(f"{name}: must be a string, got {v!r}")
        lists = ("values", "estimate", "classes", "pseudo_counts", "counts", "floors",
                 "roles", "sources")
        for name in lists:
            if name in data and not isinstance(data[name], list):
                raise ValueError(f"{name}: must be a list, got {data[name]!r}")
        for name in ("classes", "roles", "sources"):
            if any(not isinstance(x, str) for x in data.get(name, ())):
                raise ValueError(f"{name}: must be strings, got {data[name]!r}")
        if data.get("floors"):
            _floats("floors", data["floors"])
        f = data["forgetting"]
        if isinstance(f, bool) or not isinstance(f, int | float):
            raise ValueError(f"forgetting: must be a number in (0, 1], got {f!r}")
        meta = data.get("meta", {})
        if not isinstance(meta, dict):
            raise ValueError(f"meta: must be a JSON object, got {meta!r}")
        return cls(
            version=str(data["version"]), values=tuple(data["values"]),
            estimate=tuple(data["estimate"]), method=str(data["method"]),
            classes=tuple(data["classes"]), pseudo_counts=tuple(data["pseudo_counts"]),
            counts=tuple(data["counts"]), forgetting=float(f),
            floors=tuple(data.get("floors", ())), roles=tuple(data.get("roles", ())),
            sources=tuple(data.get("sources", ())), created=str(data.get("created", "")),
            meta=dict(meta))


#: Fields every document has (the others default).
_REQUIRED = ("version", "values", "estimate", "method", "classes", "pseudo_counts",
             "counts", "forgetting")


def equal_priors(version: str = "equal") -> LearnedPriors:
    """The paper's equal priors as a record (what every trial used before learning)."""
    return LearnedPriors(version=version, values=EQUAL_PRIORS, estimate=EQUAL_PRIORS)


def forgotten_counts(labels: Sequence[str], forgetting: float = DEFAULT_FORGETTING,
                     start: Sequence[float] | None = None) -> FloatArray:
    """Counts after each confirmed label in turn: `n <- gamma n + e_label`.

    Raises:
        ValueError: a label that is not a category name (named with its position).
    """
    if not 0.0 < forgetting <= 1.0:
        raise ValueError(f"forgetting must be in (0, 1], got {forgetting!r}")
    n = np.zeros(len(CATEGORY_NAMES)) if start is None else np.array(start, dtype=np.float64)
    index = {c: i for i, c in enumerate(CATEGORY_NAMES)}
    for i, lab in enumerate(labels):
        if lab not in index:
            raise ValueError(f"label {i} is {lab!r}; expected one of {', '.join(CATEGORY_NAMES)}")
        n *= forgetting
        n[index[lab]] += 1.0
    return n


def dirichlet_estimate(counts: npt.ArrayLike, pseudo_counts: npt.ArrayLike) -> FloatArray:
    """Posterior mean of a Dirichlet: `(alpha_k + n_k) / (sum alpha + N)`."""
    a = np.asarray(pseudo_counts, dtype=np.float64) + np.asarray(counts, dtype=np.float64)
    return np.asarray(a / a.sum(), dtype=np.float64)


def learn_from_confirmed(
    labels: Sequence[str],
    bounds: PriorBounds,
    *,
    sources: Sequence[str] | None = None,
    previous: LearnedPriors | None = None,
    pseudo_counts: Sequence[float] = (DEFAULT_PSEUDO_COUNT,) * len(CATEGORY_NAMES),
    forgetting: float = DEFAULT_FORGETTING,
    version: str = "1",
    meta: dict[str, Any] | None = None,
) -> LearnedPriors:
    """Priors from confirmed motions, continuing `previous` (its counts, pseudo-counts
    and forgetting) when given, projected onto `bounds`."""
    ids = [f"motion-{i}" for i in range(len(labels))] if sources is None else list(sources)
    if len(ids) != len(labels):
        raise ValueError(f"{len(ids)} sources for {len(labels)} labels")
    old_sources: tuple[str, ...] = ()
    start = None
    if previous is not None and previous.method == "dirichlet":
        pseudo_counts, forgetting = previous.pseudo_counts, previous.forgetting
        start, old_sources = previous.counts, previous.sources
    counts = forgotten_counts(labels, forgetting, start)
    est = dirichlet_estimate(counts, pseudo_counts)
    return LearnedPriors(
        version=version, values=tuple(bounds.project(est)), estimate=tuple(est),
        method="dirichlet", pseudo_counts=tuple(pseudo_counts), counts=tuple(counts),
        forgetting=forgetting, floors=bounds.floors, roles=tuple(r.value for r in bounds.roles),
        sources=(*old_sources, *ids), created=datetime.now(UTC).isoformat(timespec="seconds"),
        meta=dict(meta or {}))
