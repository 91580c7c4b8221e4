"""Trial conditions: keys, and the counterbalanced order of controllers in several
variants (`backend.study.counterbalance.condition_order`)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from backend.study import conditions
from backend.study.counterbalance import condition_order, controller_order
from controller.evaluation.study import (
    VARIANT_LABELS,
    condition_controller,
    condition_rank,
    controller_label,
)

PERSONAL = ("population", "personal")


def test_keys_keep_the_controller_name_for_population_with_equal_priors() -> None:
    assert conditions.key("umc", "population") == "umc"
    assert conditions.key("umc", "personal") == "umc+personal"
    assert conditions.key("eumc", "personal+priors") == "eumc+personal+priors"
    assert conditions.key("umc", "population+priors") == "umc+priors"
    assert max(len(conditions.key(c, v)) for c in ("umc", "eumc")
               for v in conditions.VARIANTS) <= 32  # fits the blinding key's column


def test_every_variant_has_a_label_and_a_place_in_the_tables() -> None:
    """The result tables read a condition's key back (`controller.evaluation.study`):
    each variant the plan can make is labelled there and keeps the plan's order."""
    suffixes = [s for s in conditions.VARIANTS.values() if s]
    assert suffixes == list(VARIANT_LABELS)
    keys = [conditions.key("umc", v) for v in conditions.VARIANTS]
    assert [condition_controller(k) for k in keys] == ["umc"] * len(keys)
    assert [condition_rank(k) for k in keys] == list(range(len(keys)))
    assert controller_label(conditions.key("eumc", "personal")) == "E-UMC (personal models)"


@given(position=st.integers(0, 10_000), optional=st.booleans(), baselines=st.booleans())
def test_one_variant_each_is_the_controller_order(position: int, optional: bool,
                                                   baselines: bool) -> None:
    units = condition_order(position, {}, optional, baselines)
    assert [c for c, _ in units] == controller_order(position, optional, baselines)


def test_variants_rotate_with_the_counterbalanced_controllers() -> None:
    variants = conditions.variants_of(controller_order(0, True), PERSONAL)
    assert variants["pec"] == ("population",)
    orders = [[conditions.key(c, v) for c, v in condition_order(i, variants, True)]
              for i in range(3)]
    # UMC population, UMC personal and PEC each lead once in three participants; the
    # E-UMC's two variants follow, their order alternating.
    assert [o[0] for o in orders] == ["umc", "umc+personal", "pec"]
    assert orders[0] == ["umc", "umc+personal", "pec", "eumc", "eumc+personal"]
    assert orders[1] == ["umc+personal", "pec", "umc", "eumc+personal", "eumc"]
    for o in orders:
        assert sorted(o) == sorted(orders[0])
