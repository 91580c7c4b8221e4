"""A participant's prior sets: learned (from confirmed motions or unconfirmed use),
equal or imported, always inside the safety bound of the utility set they name,
versioned per participant, and listed.

The service behind the prior-set routes of `backend/api/routes/personalisation.py`;
refusals are `backend.core.errors`. The pure methods are
`controller.intent.learned_priors`, `label_shift` and `prior_safety`: every prior set
stored here went through `PriorBounds.project` (learned) or `PriorBounds.violation`
(imported) against the utility set it names.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.analysis.participant_motions import (
    confirmed_motions,
    known_participant,
    unconfirmed_posteriors,
)
from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db import audit
from backend.db.evidence_tables import UtilitySetRecord
from backend.db.models import Participant, Study, User
from backend.db.personalisation import PriorSetRecord
from backend.schemas.personalisation import PriorSetIn
from controller.decision.utility_function import UtilitySet
from controller.intent.label_shift import learn_from_unconfirmed
from controller.intent.learned_priors import LearnedPriors, learn_from_confirmed
from controller.intent.posteriors import EQUAL_PRIORS
from controller.intent.prior_safety import N_CATEGORIES, PriorBounds


def participant_prior_sets(db: Session, participant_id: int) -> list[PriorSetRecord]:
    """The participant's prior sets, by version; `NotFoundError` for an unknown
    participant."""
    known_participant(db, participant_id)
    return list(db.scalars(select(PriorSetRecord).where(
        PriorSetRecord.participant_id == participant_id).order_by(PriorSetRecord.version)))


def study_prior_sets(db: Session, study_id: int) -> list[PriorSetRecord]:
    """Every prior set of the study's participants, oldest first; `NotFoundError` for
    an unknown study."""
    if db.get(Study, study_id) is None:
        raise NotFoundError("study", study_id)
    return list(db.scalars(select(PriorSetRecord).where(PriorSetRecord.study_id == study_id)
                           .order_by(PriorSetRecord.id)))


def one_prior_set(db: Session, prior_set_id: int) -> PriorSetRecord:
    """One prior set; `NotFoundError` for an unknown id."""
    row = db.get(PriorSetRecord, prior_set_id)
    if row is None:
        raise NotFoundError("prior set", prior_set_id)
    return row


def _utility_set(db: Session, ref: int, study_id: int) -> UtilitySetRecord:
    row = db.get(UtilitySetRecord, ref)
    if row is None or row.study_id != study_id:
        raise InvalidError.at(["body", "utility_set_id"], f"utility set {ref} is not a "
                              "utility set of this study")
    if row.status != "ready" or row.document is None:
        raise ConflictError("utility_set_id", f"utility set {ref} is {row.status}, not ready")
    return row


def _previous(db: Session, ref: int | None, participant: Participant) -> PriorSetRecord | None:
    if ref is None:
        return None
    row = db.get(PriorSetRecord, ref)
    if row is None or row.participant_id != participant.id:
        raise InvalidError.at(["body", "previous_prior_set_id"], f"prior set {ref} is not "
                              f"a prior set of participant {participant.code}")
    if row.document is None:
        raise ConflictError("previous_prior_set_id", f"prior set {ref} is {row.status}")
    return row


#: Attempts at a prior set's version number when other requests take it first.
VERSION_ATTEMPTS = 5


def learn_prior_set(db: Session, user: User, participant_id: int,
                    body: PriorSetIn) -> PriorSetRecord:
    """A new version of the participant's priors, inside the bound of `utility_set_id`
    (learned ones projected onto it, imported ones refused outside it); commits.
    `NotFoundError` for an unknown participant.

    The version is the participant's highest plus one, kept unique by the table: when
    another request stored that version first, this one starts again from the new
    highest (the document names its version, so it is learned again); after
    `VERSION_ATTEMPTS` such races, 409."""
    person = known_participant(db, participant_id)
    pid, code = person.id, person.code
    for _ in range(VERSION_ATTEMPTS):
        try:
            return _learn_prior_set(db, user, person, body)
        except IntegrityError:
            db.rollback()
            if db.scalar(select(func.count()).select_from(Participant)
                         .where(Participant.id == pid)) == 0:
                raise
    raise ConflictError("prior_set", f"other prior sets of participant {code} were being "
                        "stored at the same time; try again")


def _learn_prior_set(db: Session, user: User, participant: Participant,
                     body: PriorSetIn) -> PriorSetRecord:
    utilities = _utility_set(db, body.utility_set_id, participant.study_id)
    bounds = PriorBounds.for_table(_table(utilities), (body.floor,) * N_CATEGORIES)
    previous = _previous(db, body.previous_prior_set_id, participant)
    version = 1 + (db.scalar(select(func.max(PriorSetRecord.version)).where(
        PriorSetRecord.participant_id == participant.id)) or 0)
    label = f"{participant.code}-priors-{version}"
    meta = {"participant": participant.code, "utility_set_id": utilities.id,
            "utility_set_name": utilities.name}
    params: dict[str, Any] = {"floor": body.floor}
    priors: LearnedPriors
    if body.method == "dirichlet":
        motions = confirmed_motions(db, participant, body.include_recordings,
                                    body.gait_trials_as_other)
        before = None
        if previous is not None and previous.document is not None:
            try:
                before = LearnedPriors.from_json(previous.document)
            except ValueError as exc:
                raise ConflictError("previous_prior_set_id", f"prior set {previous.id} is "
                                    f"not a valid priors document: {exc}") from None
        current = dict(motions)
        known = _source_labels(before)
        relabelled = sorted(s for s, lab in known.items() if current.get(s, lab) != lab)
        # Sets made before sources named the motion name segment rows instead.
        row_named = before is not None and any(
            s.startswith(("trial-segment:", "segment:")) for s in before.sources)
        continued = before
        if (relabelled or row_named) and before is not None:
            # A motion the previous set counted has a new label (or cannot be matched):
            # its old label is in the previous counts, so every motion is counted afresh
            # (once, with its label now), with the previous set's pseudo-counts and
            # forgetting.
            continued = None
            if before.method == "dirichlet":
                body = body.model_copy(update={"pseudo_count": before.pseudo_counts[0],
                                               "forgetting": before.forgetting})
            new = motions
        else:
            seen = set(before.sources) if before is not None else set()
            new = [(s, lab) for s, lab in motions if s not in seen]
        if not new and before is None:
            raise InvalidError.at(["body", "method"], f"participant {participant.code} has "
                                  "no confirmed motions yet: label trial or recording "
                                  "segments, or complete walking or stairs trials")
        labels = {**(known if continued is not None else {}), **dict(new)}
        priors = learn_from_confirmed(
            [lab for _, lab in new], bounds, sources=[s for s, _ in new], previous=continued,
            pseudo_counts=(body.pseudo_count,) * N_CATEGORIES, forgetting=body.forgetting,
            version=label, meta={**meta, SOURCE_LABELS: labels})
        params.update(pseudo_count=priors.pseudo_counts[0], forgetting=priors.forgetting,
                      new_motions=len(new), include_recordings=body.include_recordings,
                      gait_trials_as_other=body.gait_trials_as_other,
                      relabelled=relabelled[:50], recounted=continued is None
                      and before is not None)
    elif body.method == "label-shift-em":
        posts, train, sources = unconfirmed_posteriors(db, participant, body.window_s)
        try:
            priors = learn_from_unconfirmed(posts, train, bounds, sources=tuple(sources),
                                            version=label)
        except ValueError as exc:
            raise ConflictError("method", f"label-shift-em cannot learn from participant "
                                f"{participant.code}'s trials: {exc}") from None
        priors = LearnedPriors.from_json({**priors.to_json(),
                                          "meta": {**priors.meta, **meta}})
        params.update(window_s=body.window_s, motions=len(sources))
    else:
        values = tuple(EQUAL_PRIORS) if body.method == "equal" else tuple(body.values or ())
        problem = bounds.violation(values)
        if problem is not None:
            raise InvalidError.at(["body", "values"], "these priors could make the "
                                  "controller lock where equal priors would not, or leave a "
                                  f"motion below its floor: {problem}")
        priors = LearnedPriors(version=label, values=values, estimate=values, method="equal",
                               floors=bounds.floors,
                               roles=tuple(r.value for r in bounds.roles),
                               meta={**meta, "source": body.method})
    row = PriorSetRecord(study_id=participant.study_id, participant_id=participant.id,
                         version=version, name=body.name, method=body.method, status="ready",
                         utility_set_id=utilities.id,
                         previous_id=None if previous is None else previous.id,
                         params=params, document=priors.to_json(), created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "create", "prior_set", row.id,
                 {"name": body.name, "method": body.method, "version": version,
                  "values": list(priors.values), "estimate": list(priors.estimate)})
    db.commit()
    return row


#: Where a learned set's document keeps each source's label when it was counted.
SOURCE_LABELS = "source_labels"


def _source_labels(priors: LearnedPriors | None) -> dict[str, str]:
    """Each counted source's label as counted (empty for a set that kept none)."""
    got = priors.meta.get(SOURCE_LABELS) if priors is not None else None
    if not isinstance(got, dict):
        return {}
    return {str(k): str(v) for k, v in got.items()}


def _table(utilities: UtilitySetRecord) -> np.ndarray:
    assert utilities.document is not None
    return np.asarray(UtilitySet.from_json(utilities.document).table.values)
