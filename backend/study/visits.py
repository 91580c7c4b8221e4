"""A participant's sessions (visits): listed, started with the exoskeleton's settings and
the hardware profile in effect, corrected; every write audited and committed here so
the routes only parse, authorise and call."""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db import audit
from backend.db.models import StudySession, User
from backend.schemas.sessions import SessionIn, SessionUpdate
from backend.study import hardware_profiles


def of_participant(db: Session, participant_id: int) -> list[StudySession]:
    """The participant's sessions in the order they happened."""
    return list(db.scalars(select(StudySession).where(
        StudySession.participant_id == participant_id)
        .order_by(StudySession.started_at, StudySession.id)))


def start(db: Session, user: User, participant_id: int, body: SessionIn) -> StudySession:
    """A new session record (started now unless the body says when); committed."""
    s = StudySession(participant_id=participant_id, kind=body.kind,
                     precompression_pct=body.precompression_pct,
                     started_at=body.started_at or datetime.now(UTC), notes=body.notes,
                     hardware_profile_id=hardware_profiles.active_id(db))
    db.add(s)
    db.flush()
    audit.record(db, user, "create", "session", s.id,
                 {"participant_id": participant_id, **body.model_dump(mode="json")})
    db.commit()
    return s


def correct(db: Session, user: User, s: StudySession, body: SessionUpdate) -> StudySession:
    """Change the fields the body sets (absent or null ones stay); committed."""
    changes = body.model_dump(mode="json", exclude_unset=True, exclude_none=True)
    for field, value in changes.items():
        setattr(s, field, value)
    audit.record(db, user, "update", "session", s.id, changes)
    db.commit()
    return s
