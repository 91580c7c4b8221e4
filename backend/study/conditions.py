"""Trial conditions beyond the controller: which motion models (the study's population
set or the participant's personal set) and which priors (equal, or a prior set learned
from the participant's use) a controller runs with.

A condition is blinded and counterbalanced like a controller: its key ("umc",
"umc+personal", "umc+priors", "umc+personal+priors") is what the blinding key
(`ConditionLabel.controller`) maps a letter to, and the plan rotates the variants of the
counterbalanced controllers together (`counterbalance.condition_order`). Only the
controllers with motion models have variants; the PEC and the baselines run once.

Also here: what a trial's condition resolves to when it starts (the personal set and
the prior set, each checked again), so the stored snapshot says exactly what ran.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, Literal

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError
from backend.db.evidence_tables import ModelSetRecord, UtilitySetRecord
from backend.db.models import ConditionLabel, Participant
from backend.db.personalisation import PriorSetRecord
from backend.study.counterbalance import LABELS
from controller.controllers.factory import load_utilities, needs_models
from controller.controllers.spec import ControllerSpec
from controller.intent.learned_priors import LearnedPriors
from controller.intent.posteriors import EQUAL_PRIORS
from controller.intent.prior_safety import PriorBounds

#: The plan's names of the variants, and the suffix each adds to the controller's name.
Variant = Literal["population", "personal", "population+priors", "personal+priors"]
VARIANTS: dict[str, str] = {"population": "", "personal": "personal",
                            "population+priors": "priors",
                            "personal+priors": "personal+priors"}
#: The trial's task name of a demonstration block (controller `none`, no locks).
DEMONSTRATION_TASK = "demonstrations"


def key(controller: str, variant: str) -> str:
    """The blinding key of `controller` in `variant` (the controller's own name for the
    population models with equal priors, as before conditions existed)."""
    suffix = VARIANTS[variant]
    return f"{controller}+{suffix}" if suffix else controller


def uses_personal(variant: str) -> bool:
    """Whether the variant runs the participant's personal model set."""
    return variant.startswith("personal")


def uses_priors(variant: str) -> bool:
    """Whether the variant runs the plan's prior set."""
    return variant.endswith("+priors")


def variants_of(order_names: Iterable[str], variants: Sequence[str]
                ) -> dict[str, tuple[str, ...]]:
    """Each controller's variants in the plan: all asked for where it uses motion
    models, the population one alone elsewhere."""
    return {c: tuple(variants) if needs_models(c) else ("population",) for c in order_names}


def assign_labels(db: Session, participant_id: int, keys: Sequence[str]) -> dict[str, str]:
    """Labels of the plan's condition keys: an existing one kept (a participant keeps a
    condition's letter over sessions); a new one gets the first letter not yet used by
    that participant, in the order met. Adds the new rows; returns key -> label."""
    rows = list(db.scalars(select(ConditionLabel).where(
        ConditionLabel.participant_id == participant_id)))
    existing = {c.controller: c.label for c in rows}
    used = set(existing.values())
    out: dict[str, str] = {}
    for k in keys:
        if k in out:
            continue
        if k in existing:
            out[k] = existing[k]
            continue
        free = next((lab for lab in LABELS if lab not in used), None)
        if free is None:
            raise ConflictError("conditions", f"participant {participant_id} has used all "
                                f"{len(LABELS)} condition labels")
        used.add(free)
        out[k] = free
        db.add(ConditionLabel(participant_id=participant_id, label=free, controller=k))
    return out


def check_personal_set(db: Session, ref: int, participant: Participant,
                       loc: list[str | int]) -> ModelSetRecord:
    """A personal model set a plan names: this participant's, and ready."""
    row = db.get(ModelSetRecord, ref)
    if row is None:
        raise InvalidError.at(loc, f"model set {ref} does not exist")
    if row.kind != "personal" or row.participant_id != participant.id:
        raise InvalidError.at(loc, f"model set {ref} is not a personal model set of "
                              f"participant {participant.code}")
    if row.status != "ready" or row.document is None:
        raise ConflictError(loc[-1] if isinstance(loc[-1], str) else "model_set_id",
                            f"model set {ref} is {row.status}, not ready")
    return row


def latest_personal_set(db: Session, participant_id: int) -> ModelSetRecord | None:
    """The participant's newest ready personal model set."""
    return db.scalar(select(ModelSetRecord).where(
        ModelSetRecord.participant_id == participant_id, ModelSetRecord.kind == "personal",
        ModelSetRecord.status == "ready").order_by(ModelSetRecord.id.desc()).limit(1))


def bounds_of(utilities: UtilitySetRecord, floors: Sequence[float] = ()) -> PriorBounds:
    """The safety bound of a utility set's table: the roles always from the table
    itself, the floors given (a prior set's own, chosen when it was learned) or the
    default ones."""
    assert utilities.document is not None
    from controller.decision.utility_function import UtilitySet

    table = np.asarray(UtilitySet.from_json(utilities.document).table.values)
    return (PriorBounds.for_table(table, tuple(floors)) if floors
            else PriorBounds.for_table(table))


def checked_priors(row: PriorSetRecord, utilities: UtilitySetRecord | None,
                   field: str = "prior_set_id") -> LearnedPriors:
    """A stored prior set as the controller will get it, re-checked: a valid document,
    and values inside the safety bound of the utility set the trial runs (not only the
    bound the document says it was made with: a row altered after it was stored is
    refused here, and the controller in the worker refuses it again).

    Raises:
        ConflictError: the set is not ready, is malformed or is outside the bound.
    """
    if row.status != "ready" or row.document is None:
        raise ConflictError(field, f"prior set {row.id} is {row.status}, not ready")
    try:
        priors = LearnedPriors.from_json(row.document)
    except ValueError as exc:
        raise ConflictError(field, f"prior set {row.id} is not a valid priors document: "
                            f"{exc}") from None
    if utilities is not None and utilities.document is not None:
        try:
            bounds = bounds_of(utilities, priors.floors)
        except ValueError:
            bounds = bounds_of(utilities)
        problem = bounds.violation(priors.values)
        if problem is not None:
            raise ConflictError(field, f"prior set {row.id} is outside the safety bound of "
                                f"utility set {utilities.id}: {problem}")
    return priors


def check_plan_prior_set(db: Session, ref: int, participant: Participant,
                         utilities: UtilitySetRecord | None) -> PriorSetRecord:
    """The prior set a plan names: this participant's, ready, inside the bound of the
    plan's utility set (422 naming the problem)."""
    row = db.get(PriorSetRecord, ref)
    if row is None:
        raise InvalidError.at(["body", "prior_set_id"], f"prior set {ref} does not exist")
    if row.participant_id != participant.id:
        raise InvalidError.at(["body", "prior_set_id"], f"prior set {ref} belongs to "
                              f"another participant, not {participant.code}")
    try:
        checked_priors(row, utilities)
    except ConflictError as exc:
        raise InvalidError.at(["body", "prior_set_id"], exc.problem) from None
    return row


def spec_priors_problem(spec: ControllerSpec) -> str | None:
    """Why a controller specification's priors are outside the safety bound of its own
    utility set (the one it will run), or None: checked where priors arrive from
    outside (a request body), before the worker (which refuses them again) sees them."""
    if not needs_models(spec.name) or tuple(spec.settings.priors) == tuple(EQUAL_PRIORS):
        return None
    try:
        table = np.asarray(load_utilities(spec).table.values)
    except (OSError, ValueError) as exc:
        return f"the utility set cannot be read to check them: {exc}"
    problem = PriorBounds.for_table(table).violation(spec.settings.priors)
    if problem is None:
        return None
    return (f"{list(spec.settings.priors)} could make the controller lock where equal "
            f"priors would not ({problem}); see docs/personalisation.md")


def snapshot_of_priors(row: PriorSetRecord, priors: LearnedPriors) -> dict[str, Any]:
    """What a trial's stored configuration says about its priors."""
    return {"id": row.id, "version": row.version, "name": row.name, "method": row.method,
            "participant_id": row.participant_id, "utility_set_id": row.utility_set_id,
            "values": list(priors.values), "estimate": list(priors.estimate),
            "sources": len(priors.sources), "document_version": priors.version}


def snapshot_of_models(row: ModelSetRecord) -> dict[str, Any]:
    """What a trial's stored configuration says about its model set (with the
    provenance of a personal set)."""
    doc = row.document or {}
    out: dict[str, Any] = {"id": row.id, "name": row.name, "version": doc.get("version"),
                           "kind": row.kind, "method": row.method}
    if row.kind == "personal":
        out.update(participant_id=row.participant_id, base_model_set_id=row.base_model_set_id,
                   personal=(doc.get("meta") or {}).get("personal"))
    return out
