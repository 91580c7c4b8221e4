"""The count-based priors and their versioned record."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.intent.learned_priors import (
    LearnedPriors,
    dirichlet_estimate,
    equal_priors,
    forgotten_counts,
    learn_from_confirmed,
)
from controller.intent.prior_safety import ClassRole, PriorBounds
from controller.tick_record import CATEGORY_NAMES

BOUNDS = PriorBounds((ClassRole.FAVOURS_LOCK, ClassRole.MIXED, ClassRole.MIXED,
                      ClassRole.OPPOSES_LOCK))


def test_dirichlet_estimate_without_forgetting() -> None:
    n = forgotten_counts(["squat", "squat", "other", "stoop_left"], forgetting=1.0)
    assert n.tolist() == [2.0, 1.0, 0.0, 1.0]
    est = dirichlet_estimate(n, [1, 1, 1, 1])
    assert est.tolist() == pytest.approx([3 / 8, 2 / 8, 1 / 8, 2 / 8])


def test_forgetting_weighs_a_motion_t_confirmations_ago_by_gamma_to_the_t() -> None:
    n = forgotten_counts(["squat", "other", "other"], forgetting=0.5)
    assert n.tolist() == [0.25, 0.0, 0.0, 1.5]


@settings(max_examples=50, deadline=None)
@given(labels=st.lists(st.sampled_from(CATEGORY_NAMES), max_size=200),
       gamma=st.floats(0.5, 1.0))
def test_estimate_is_a_distribution_and_counts_are_bounded(labels: list[str],
                                                           gamma: float) -> None:
    n = forgotten_counts(labels, gamma)
    assert n.sum() == pytest.approx(sum(gamma ** t for t in range(len(labels))))
    est = dirichlet_estimate(n, [2.5] * 4)
    assert est.sum() == pytest.approx(1.0) and (est > 0).all()


def test_record_round_trips_and_continues() -> None:
    first = learn_from_confirmed(["stoop_left"] * 10, BOUNDS, sources=[f"L{i}" for i in range(10)])
    assert first.estimate[1] > 0.5 and BOUNDS.violation(first.values) is None
    again = LearnedPriors.from_json(json.loads(json.dumps(first.to_json())))
    assert again == first
    more = learn_from_confirmed(["squat"], BOUNDS, previous=first, sources=["L10"])
    assert more.sources[-1] == "L10" and len(more.sources) == 11
    assert more.counts[0] == 1.0 and more.counts[1] == pytest.approx(first.counts[1] * 0.99)


def test_bad_records_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="label 1 is 'walk'"):
        forgotten_counts(["squat", "walk"])
    with pytest.raises(ValueError, match="values: outside their safety bound"):
        LearnedPriors("x", (0.1, 0.6, 0.1, 0.2), (0.1, 0.6, 0.1, 0.2), method="dirichlet",
                      floors=BOUNDS.floors, roles=tuple(r.value for r in BOUNDS.roles))
    with pytest.raises(ValueError, match="classes"):
        LearnedPriors("x", (0.25,) * 4, (0.25,) * 4, classes=("a", "b", "c", "d"))
    with pytest.raises(ValueError, match="lacks field 'values'"):
        doc = equal_priors().to_json()
        del doc["values"]
        LearnedPriors.from_json(doc)
    assert equal_priors().values == (0.25,) * 4
    assert np.isclose(sum(equal_priors().estimate), 1.0)


@pytest.mark.parametrize(("field", "value", "named"), [
    ("values", 5, "values"), ("meta", 5, "meta"), ("forgetting", None, "forgetting"),
    ("forgetting", True, "forgetting"), ("estimate", "0.25", "estimate"),
    ("classes", [1, 2, 3, 4], "classes"), ("roles", ["x"] * 4, "x"),
    ("floors", [1e-12] * 4, "floors"), ("floors", ["a"] * 4, "floors"),
    ("sources", 7, "sources"), ("version", [], "version"), ("counts", {}, "counts"),
])
def test_forged_documents_are_refused_with_a_value_error_naming_the_field(
        field: str, value: object, named: str) -> None:
    doc = learn_from_confirmed(["squat"], BOUNDS).to_json()
    doc[field] = value
    with pytest.raises(ValueError, match=named):
        LearnedPriors.from_json(doc)


@settings(max_examples=60, deadline=None)
@given(doc=st.one_of(
    st.lists(st.integers(), max_size=3),
    st.dictionaries(st.sampled_from(["version", "values", "estimate", "method", "classes",
                                     "pseudo_counts", "counts", "forgetting", "floors",
                                     "roles", "sources", "created", "meta"]),
                    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(),
                              st.text(max_size=3), st.lists(st.floats(), max_size=5),
                              st.dictionaries(st.text(max_size=2), st.integers(),
                                              max_size=2)))))
def test_any_document_is_a_record_or_a_value_error(doc: object) -> None:
    """Whatever a stored row holds, reading it raises ValueError or succeeds."""
    if isinstance(doc, dict):
        doc = {**learn_from_confirmed(["squat"], BOUNDS).to_json(), **doc}
    try:
        LearnedPriors.from_json(doc)
    except ValueError:
        pass
