"""One recording's evaluation, labelled with its participant and condition.

The paper's tables are per participant and controller, and one participant-controller
pair has several recordings (the squat trial, the stoop trial, the walking and the
stair-walking trial). A `RecordingEvaluation` is the unit the tables and figures
aggregate; a study is just a sequence of them.

A study that runs one controller in several conditions (its population or the wearer's
own motion models, equal or learned priors) labels each recording with the condition's
key, "controller+variant" ("umc+personal"); the controller's plain name is the
population models with equal priors, the paper's controller. Tables then keep the
conditions apart, as the questionnaires (answered per blinded condition) do.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from controller.controllers import registry
from controller.evaluation.columns import Columns, TickData
from controller.evaluation.lifts import GaitTrial, Lift
from controller.evaluation.metrics import (
    FalsePositives,
    LiftOutcome,
    count_false_positives,
    evaluate_lifts,
)

#: How a condition's variant reads after its controller's name, in the order tables
#: list a controller's conditions (after its plain name).
VARIANT_LABELS = {"personal": "personal models", "priors": "learned priors",
                  "personal+priors": "personal models, learned priors"}


def condition_controller(key: str) -> str:
    """The controller a condition key runs ("umc+personal" -> "umc")."""
    return key.partition("+")[0]


def condition_rank(key: str) -> int:
    """Where a condition comes among its controller's: the plain name first, then the
    variants in `VARIANT_LABELS` order, an unknown variant last."""
    variant = key.partition("+")[2]
    if not variant:
        return 0
    order = list(VARIANT_LABELS)
    return 1 + (order.index(variant) if variant in order else len(order))


def controller_label(name: str) -> str:
    """The display name a controller registered (`controller.controllers.registry`), with
    its condition's variant for a condition key ("UMC (personal models)"); an unknown
    name is shown as given."""
    base, _, variant = name.partition("+")
    shown = registry.label(base.lower())
    return f"{shown} ({VARIANT_LABELS.get(variant, variant)})" if variant else shown


def table_controllers(intent_only: bool = False) -> tuple[str, ...]:
    """The planned controllers (`controller.controllers.registry.PlanPlace`) in the order
    of the paper's tables: those that estimate no intent first (the PEC), then the others by
    plan rank (UMC, E-UMC); `intent_only`: only those that estimate intent (the
    performance table: no intent, no recognised or correct lifts)."""
    regs = [r for r in registry.planned() if r.estimates_intent or not intent_only]
    return tuple(r.name for r in sorted(regs, key=lambda r: r.estimates_intent))


def table_conditions(present: Iterable[str], intent_only: bool = False) -> tuple[str, ...]:
    """The columns of a study's tables: each of `table_controllers` followed by its other
    conditions found in `present` (personal models, learned priors: their keys, in
    `VARIANT_LABELS` order), so a plan's conditions of one controller are compared side
    by side instead of pooled."""
    found = set(present)
    out: list[str] = []
    for c in table_controllers(intent_only):
        out.append(c)
        out.extend(sorted((k for k in found if k != c and condition_controller(k) == c),
                          key=lambda k: (condition_rank(k), k)))
    return tuple(out)


def in_order(evaluations: Sequence[RecordingEvaluation],
             order: Sequence[str] | None = None) -> list[str]:
    """The conditions of `evaluations` that have lifts: those in `order` first, in its
    order, then any other as it appears."""
    present = [e.controller for e in evaluations if e.lifts]
    found = set(present)
    return [c for c in dict.fromkeys([*(order or ()), *present]) if c in found]


@dataclass(frozen=True, slots=True)
class RecordingEvaluation:
    """Per-lift outcomes and per-trial false positives of one recording.

    Attributes:
        participant: the participant's label as tables show it ("1", "P03").
        controller: the controller's name ("umc", "eumc", "pec", or any other), or the
            condition's key where the study ran it in several ("umc+personal").
        lifts: one outcome per lift in the recording.
        false_positives: one count per walking or stair-walking trial in it.
        recording: an optional identifier of the recording (session id, file name).
    """

    participant: str
    controller: str
    lifts: tuple[LiftOutcome, ...] = ()
    false_positives: tuple[FalsePositives, ...] = ()
    recording: str = ""


def evaluate_recording(
    columns: Columns,
    participant: str,
    controller: str,
    lifts: Sequence[Lift] = (),
    trials: Sequence[GaitTrial] = (),
    recording: str = "",
    with_intent: bool | None = None,
) -> RecordingEvaluation:
    """Evaluate one recording: its lifts (`evaluate_lifts`) and its gait trials
    (`count_false_positives`). A lifting trial passes only `lifts`, a walking trial
    only `trials`; a simulated whole protocol can pass both.

    `with_intent`: whether the controller estimates intent; None takes what a
    registered controller declares (`Registration.estimates_intent`), else infers it
    from the data. Declared rather than inferred for a known controller: an E-UMC whose
    trigger never fired in a trial computed no posterior, yet its lifts were not
    recognised (False, not None).
    """
    cols = TickData.of(columns)
    intent = (registry.estimates_intent(condition_controller(controller).lower())
              if with_intent is None else with_intent)
    return RecordingEvaluation(
        participant=str(participant),
        controller=str(controller),
        lifts=tuple(evaluate_lifts(cols, lifts, intent)),
        false_positives=tuple(count_false_positives(cols, trials)),
        recording=recording,
    )

