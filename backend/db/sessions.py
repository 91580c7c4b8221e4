"""Which study a session belongs to: a lookup the lab (a session's marker buttons) and
the EMG inlets (a session's processing chain) both need, so it sits with the tables,
below both."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db.models import Participant, StudySession


def study_of_session(db: Session, session_id: int) -> int | None:
    """The study a session belongs to (None for an unknown session)."""
    return db.scalar(select(Participant.study_id).join(
        StudySession, StudySession.participant_id == Participant.id)
        .where(StudySession.id == session_id))
