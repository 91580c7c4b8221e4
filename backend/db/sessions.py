"""Which study a session belongs to, and one row that belongs to a session: lookups
the lab (a session's marker buttons) and the EMG services (a session's processing chain,
its subscriptions, recordings and MVC steps) both need, so they sit with the tables,
below both."""

from __future__ import annotations

from typing import Protocol, TypeVar

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import NotFoundError
from backend.db.models import Participant, StudySession


class OfSession(Protocol):
    """A row that belongs to one session."""

    @property
    def session_id(self) -> int: ...


Row = TypeVar("Row", bound=OfSession)


def study_of_session(db: Session, session_id: int) -> int | None:
    """The study a session belongs to (None for an unknown session)."""
    return db.scalar(select(Participant.study_id).join(
        StudySession, StudySession.participant_id == Participant.id)
        .where(StudySession.id == session_id))


def session_row(db: Session, model: type[Row], session_id: int, key: int, entity: str
                ) -> Row:
    """Row `key` of `model` if it belongs to the session; `NotFoundError` naming the
    entity otherwise (a row of another session is not found under this one)."""
    row = db.get(model, key)
    if row is None or row.session_id != session_id:
        raise NotFoundError(entity, key)
    return row
