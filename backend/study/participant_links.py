"""Participant links: a single-use token that asks one participant for some forms (each
pinned to one instrument row, about a blinded condition) and perhaps their preference.
Only the token's digest is stored; the token is handed out once, at creation."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import InvalidError
from backend.core.security import new_token, token_digest
from backend.db import audit
from backend.db.models import (
    Participant,
    ParticipantLink,
    Preference,
    QuestionnaireInstrument,
    QuestionnaireResponse,
    User,
)
from backend.schemas.questionnaires import LinkIn
from backend.study import instruments
from backend.study.blinding import labels_of
from backend.study.writes import commit_or_conflict

#: A form's identity on a link: instrument key, version, condition label.
FormKey = tuple[str, str, str | None]


def form_key(form: dict[str, Any]) -> FormKey:
    """The identity of one of a link's `forms_due`."""
    return (str(form["instrument_key"]), str(form["instrument_version"]),
            form["condition_label"])


def create(db: Session, user: User, participant: Participant, body: LinkIn
           ) -> tuple[ParticipantLink, str]:
    """A new link and its token (not stored, only its digest). Every problem with the
    forms asked for is named at once (`InvalidError`). Audited, committed."""
    if not body.forms and not body.preference:
        raise InvalidError.at(["body", "forms"],
                              "a link must ask for at least one form or the preference")
    labels = labels_of(db, participant.id)
    problems: list[tuple[list[str | int], str]] = []
    due: list[dict[str, str | int | None]] = []
    for i, form in enumerate(body.forms):
        inst = instruments.resolve_for_link(db, participant.study_id, form.instrument_key,
                                            form.instrument_version)
        if isinstance(inst, str):
            problems.append((["body", "forms", i, "instrument_key"], inst))
            continue
        if form.condition_label is not None and form.condition_label not in labels:
            problems.append((["body", "forms", i, "condition_label"],
                             f"{form.condition_label!r} is not a condition of this participant"
                             f" (known: {sorted(labels)})"))
            continue
        entry: dict[str, str | int | None] = {
            "instrument_id": inst.id, "instrument_key": inst.key,
            "instrument_version": inst.version, "condition_label": form.condition_label}
        if entry in due:
            problems.append((["body", "forms", i], "the same form is already due on this link"))
            continue
        due.append(entry)
    if body.preference and not labels:
        problems.append((["body", "preference"], "the participant has no blinded conditions "
                         "to choose from (POST .../conditions first)"))
    if problems:
        raise InvalidError(problems)
    token = new_token()
    now = datetime.now(UTC)
    link = ParticipantLink(participant_id=participant.id, token_hash=token_digest(token),
                           forms_due=due, preference_due=body.preference, created_by=user.id,
                           created_at=now, expires_at=now + timedelta(hours=body.valid_hours))
    db.add(link)
    db.flush()
    audit.record(db, user, "create", "participant_link", link.id,
                 {"participant_id": participant.id, "forms_due": due,
                  "preference_due": body.preference})
    commit_or_conflict(db, "token", "token collision, try again")
    return link, token


def of_participant(db: Session, participant_id: int) -> list[ParticipantLink]:
    """The participant's links, oldest first."""
    return list(db.scalars(select(ParticipantLink).where(
        ParticipantLink.participant_id == participant_id).order_by(ParticipantLink.id)))


def by_token(db: Session, token: str) -> ParticipantLink | None:
    """The link a token opens, open or not (the caller says which refusal)."""
    return db.scalars(select(ParticipantLink).where(
        ParticipantLink.token_hash == token_digest(token))).first()


def submitted(db: Session, link: ParticipantLink) -> tuple[set[FormKey], bool]:
    """The forms answered through the link, and whether the preference was given."""
    done = {(r.instrument_key, r.instrument_version, r.condition_label)
            for r in db.scalars(select(QuestionnaireResponse).where(
                QuestionnaireResponse.link_id == link.id))}
    pref = db.scalars(select(Preference.id).where(Preference.link_id == link.id)).first()
    return done, pref is not None


def instrument_of(db: Session, link: ParticipantLink, form: dict[str, Any]
                  ) -> QuestionnaireInstrument | None:
    """The instrument row the link pinned for this form: a built-in or one of the
    participant's study, never another study's row with the same key and version
    (None: it is gone)."""
    row = db.get(QuestionnaireInstrument, form["instrument_id"]) if form.get(
        "instrument_id") is not None else None
    if row is not None and not row.built_in:
        participant = db.get(Participant, link.participant_id)
        if participant is None or row.study_id != participant.study_id:
            row = None
    return row
