"""One recording's evaluation, labelled with its participant and controller.

The paper's tables are per participant and controller, and one participant-controller
pair has several recordings (the squat trial, the stoop trial, the walking and the
stair-walking trial). A `RecordingEvaluation` is the unit the tables and figures
aggregate; a study is just a sequence of them.
"""

from __future__ import annotations

from collections.abc import Sequence
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


def controller_label(name: str) -> str:
    """The display name a controller registered (`controller.controllers.registry`); an unknown
    name is shown as given."""
    return registry.label(name.lower())


@dataclass(frozen=True, slots=True)
class RecordingEvaluation:
    """Per-lift outcomes and per-trial false positives of one recording.

    Attributes:
        participant: the participant's label as tables show it ("1", "P03").
        controller: the controller's name ("umc", "eumc", "pec", or any other).
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
    intent = (registry.estimates_intent(controller.lower()) if with_intent is None
              else with_intent)
    return RecordingEvaluation(
        participant=str(participant),
        controller=str(controller),
        lifts=tuple(evaluate_lifts(cols, lifts, intent)),
        false_positives=tuple(count_false_positives(cols, trials)),
        recording=recording,
    )

