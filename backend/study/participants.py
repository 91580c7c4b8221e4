"""Enrolling participants, correcting their records and blinding controllers behind
labels for them.

The service behind `backend/api/routes/participants.py`; refusals are
`backend.core.errors`. A member limited to one site (`site`) enrols into and keeps
participants in that site only.
"""

from __future__ import annotations

from datetime import date
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError
from backend.db import audit
from backend.db.models import ConditionLabel, ConsentDocument, Participant, User
from backend.schemas.participants import ConditionIn, ParticipantIn, ParticipantUpdate
from backend.study.writes import commit_or_conflict
from controller.controllers.factory import controller_names


def _code_taken(db: Session, study_id: int, code: str, but: int | None = None) -> bool:
    found = db.scalars(select(Participant.id).where(
        Participant.study_id == study_id, Participant.code == code)).first()
    return found is not None and found != but


def _check_consent_version(db: Session, study_id: int, version: str | None) -> None:
    if version is not None and db.scalars(select(ConsentDocument.id).where(
            ConsentDocument.study_id == study_id, ConsentDocument.version == version)
            ).first() is None:
        raise InvalidError.at(["body", "consent_version"], f"study {study_id} has no "
                              f"consent version {version!r}")


def enrol(db: Session, user: User, study_id: int, body: ParticipantIn,
          site: str | None) -> Participant:
    """A new participant under a pseudonymous code unique in the study; commits."""
    if site is not None:
        if body.site not in (None, site):
            raise InvalidError.at(["body", "site"], f"you may enrol into your site {site!r} "
                                  "only")
        body = body.model_copy(update={"site": site})
    _check_consent_version(db, study_id, body.consent_version)
    if _code_taken(db, study_id, body.code):
        raise ConflictError("code", f"participant {body.code!r} exists in study {study_id}")
    p = Participant(study_id=study_id, **body.model_dump())
    db.add(p)
    db.flush()
    audit.record(db, user, "create", "participant", p.id, body.model_dump(mode="json"))
    commit_or_conflict(db, "code", f"participant {body.code!r} exists in study {study_id}")
    return p


def _json(v: Any) -> Any:
    return v.isoformat() if isinstance(v, date) else v


def correct(db: Session, user: User, p: Participant, body: ParticipantUpdate,
            site: str | None) -> Participant:
    """Apply the fields `body` sets (`null` clears an optional one), audited with the
    values before and after; commits."""
    changes: dict[str, Any] = body.model_dump(exclude_unset=True)
    for required in ("code", "notes"):
        if required in changes and changes[required] is None:
            raise InvalidError.at(["body", required], "cannot be null")
    if site is not None and changes.get("site", site) != site:
        raise InvalidError.at(["body", "site"], f"you may keep participants in your site "
                              f"{site!r} only")
    if "consent_version" in changes:
        _check_consent_version(db, p.study_id, changes["consent_version"])
    if "code" in changes and _code_taken(db, p.study_id, changes["code"], but=p.id):
        raise ConflictError("code", f"participant {changes['code']!r} exists in study "
                            f"{p.study_id}")
    before = {k: _json(getattr(p, k)) for k in changes}
    for field, value in changes.items():
        setattr(p, field, value)
    audit.record(db, user, "update", "participant", p.id, {
        "before": before, "after": body.model_dump(mode="json", exclude_unset=True)})
    commit_or_conflict(db, "code", "this code exists in the study")
    return p


def of_study(db: Session, study_id: int, site: str | None) -> list[Participant]:
    """The study's participants by code (`site`: only that site's)."""
    q = select(Participant).where(Participant.study_id == study_id)
    if site is not None:
        q = q.where(Participant.site == site)
    return list(db.scalars(q.order_by(Participant.code)))


def conditions_of(db: Session, participant_id: int) -> list[ConditionLabel]:
    """The participant's blinded labels with the controllers, by label (the caller
    decides who may see the controllers)."""
    return list(db.scalars(select(ConditionLabel).where(
        ConditionLabel.participant_id == participant_id).order_by(ConditionLabel.label)))


def add_condition(db: Session, user: User, participant_id: int, body: ConditionIn
                  ) -> ConditionLabel:
    """Blind a controller behind a label for this participant; a label or controller
    that already has an entry is a conflict (a key never changes once forms may use
    it). Commits."""
    if body.controller not in controller_names():
        raise InvalidError.at(["body", "controller"], f"unknown controller "
                              f"{body.controller!r}; one of {list(controller_names())}")
    existing = db.scalars(select(ConditionLabel).where(
        ConditionLabel.participant_id == participant_id)).all()
    if any(c.label == body.label for c in existing):
        raise ConflictError("label", f"label {body.label!r} is already used for this "
                            "participant")
    if any(c.controller == body.controller for c in existing):
        raise ConflictError("controller", f"{body.controller!r} already has a label for "
                            "this participant")
    c = ConditionLabel(participant_id=participant_id, label=body.label,
                       controller=body.controller)
    db.add(c)
    db.flush()
    audit.record(db, user, "create", "condition_label", c.id,
                 {"participant_id": participant_id, **body.model_dump()})
    commit_or_conflict(db, "label", "this label or controller is already used")
    return c
