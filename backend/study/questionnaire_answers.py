"""What participants answer through their links: scored questionnaire responses and
condition preferences, stored with the link that asked and listed for the experimenter.
Storing closes the link when nothing due is left."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError
from backend.db import audit
from backend.db.models import (
    ParticipantLink,
    Preference,
    QuestionnaireInstrument,
    QuestionnaireResponse,
)
from backend.schemas.questionnaires import SubmissionOut
from backend.study.participant_links import form_key, submitted


def _flush_or_conflict(db: Session, field: str, problem: str) -> None:
    """Write now: a parallel submission that got there first makes the database refuse
    this one (unique link and form), which is a conflict, not a second stored answer."""
    try:
        db.flush()
    except IntegrityError as exc:
        db.rollback()
        raise ConflictError(field, problem) from exc


def _receipt(db: Session, link: ParticipantLink) -> SubmissionOut:
    """Close the link when everything due is in; the caller commits."""
    done, pref_done = submitted(db, link)
    forms_left = sum(1 for f in link.forms_due if form_key(f) not in done)
    pref_left = link.preference_due and not pref_done
    if forms_left == 0 and not pref_left:
        link.used_at = datetime.now(UTC)
    return SubmissionOut(forms_remaining=forms_left, preference_remaining=pref_left,
                         link_closed=link.used_at is not None)


def store_response(db: Session, link: ParticipantLink, form: int,
                   inst: QuestionnaireInstrument, answers: dict[str, Any], score: float,
                   subscales: dict[str, float], substituted: list[str]) -> SubmissionOut:
    """Store the scored answers to the link's form number `form` (a second answer to
    it is a conflict); audited under the link, committed."""
    key, version, label = form_key(link.forms_due[form])
    resp = QuestionnaireResponse(
        participant_id=link.participant_id, link_id=link.id, instrument_id=inst.id,
        instrument_key=key, instrument_version=version, condition_label=label,
        answers=answers, score=score, subscale_scores=subscales, link_form=form)
    db.add(resp)
    _flush_or_conflict(db, "form", "this form was already answered")
    audit.record(db, f"participant link {link.id}", "submit", "questionnaire_response",
                 resp.id, {"participant_id": link.participant_id, "instrument": key,
                           "version": version, "condition_label": label,
                           "substituted": substituted})
    receipt = _receipt(db, link)
    db.commit()
    return receipt


def store_preference(db: Session, link: ParticipantLink, choice: str) -> SubmissionOut:
    """Store the preferred label (or "none"); a second one is a conflict. Audited under
    the link, committed."""
    pref = Preference(participant_id=link.participant_id, link_id=link.id, choice=choice)
    db.add(pref)
    _flush_or_conflict(db, "preference", "the preference was already given")
    audit.record(db, f"participant link {link.id}", "submit", "preference", pref.id,
                 {"participant_id": link.participant_id, "choice": choice})
    receipt = _receipt(db, link)
    db.commit()
    return receipt


def responses_of(db: Session, participant_id: int) -> list[QuestionnaireResponse]:
    """The participant's scored responses, in the order they came."""
    return list(db.scalars(select(QuestionnaireResponse).where(
        QuestionnaireResponse.participant_id == participant_id)
        .order_by(QuestionnaireResponse.id)))


def preferences_of(db: Session, participant_id: int) -> list[Preference]:
    """The participant's preferences, in the order they came."""
    return list(db.scalars(select(Preference).where(Preference.participant_id == participant_id)
                           .order_by(Preference.id)))
