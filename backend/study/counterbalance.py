"""The evaluation order and the blinded labels participants see.

Which controllers a plan holds and where is what each controller declares when it
registers (`controller.controllers.registry.PlanPlace`): the paper's plan is UMC and PEC in
balanced order across the study's participants, E-UMC (optional) after them.

A participant's position in the study (by enrolment, i.e. id order) decides: the
counterbalanced controllers, in plan rank order, are rotated by the position, so with
two of them even positions get the first (UMC) first and odd positions the other (PEC),
and any two consecutive participants balance each other (with more, every controller
leads equally often over as many consecutive participants). The others follow in rank
order. Labels are letters in the order the participant meets the controllers ("A"
first), so the label itself says nothing about the controller.
"""

from __future__ import annotations

import string

from controller.controllers import registry

LABELS = tuple(string.ascii_uppercase)


def controller_order(position: int, include_optional: bool = True,
                     include_baselines: bool = False) -> list[str]:
    """Controllers in the order participant number `position` (0-based) evaluates them;
    `include_optional`: with the controllers registered as optional in a plan;
    `include_baselines`: with the baseline conditions, rotated with the counterbalanced
    controllers so that they are blinded and balanced like them."""
    if position < 0:
        raise ValueError("position must be >= 0")
    planned = [r for r in registry.planned(include_baselines)
               if r.plan is not None and (include_optional or not r.plan.optional)]
    rotated = [r.name for r in planned if r.plan is not None and r.plan.counterbalanced]
    k = position % len(rotated) if rotated else 0
    following = [r.name for r in planned if r.plan is not None and not r.plan.counterbalanced]
    return [*rotated[k:], *rotated[:k], *following]


def blinded_labels(order: list[str]) -> dict[str, str]:
    """Controller name -> label, in the order met."""
    return {c: LABELS[i] for i, c in enumerate(order)}


def condition_order(position: int, variants: dict[str, tuple[str, ...]],
                    include_optional: bool = True, include_baselines: bool = False
                    ) -> list[tuple[str, str]]:
    """(controller, variant) pairs in the order participant `position` meets them, for a
    plan where some controllers run in several variants (e.g. population and personal
    models; `variants[name]`, default one unnamed variant). The counterbalanced
    controllers' variants are rotated together, as one list, exactly as
    `controller_order` rotates the controllers alone; the variants of each following
    controller are rotated by the position among themselves, so a comparison of its
    variants is balanced too. With one variant each this is `controller_order`."""
    if position < 0:
        raise ValueError("position must be >= 0")
    planned = [r for r in registry.planned(include_baselines)
               if r.plan is not None and (include_optional or not r.plan.optional)]

    def expand(name: str) -> list[tuple[str, str]]:
        return [(name, v) for v in variants.get(name, ("",))]

    rotated = [p for r in planned if r.plan is not None and r.plan.counterbalanced
               for p in expand(r.name)]
    k = position % len(rotated) if rotated else 0
    following: list[tuple[str, str]] = []
    for r in planned:
        if r.plan is not None and not r.plan.counterbalanced:
            own = expand(r.name)
            j = position % len(own)
            following += [*own[j:], *own[:j]]
    return [*rotated[k:], *rotated[:k], *following]
