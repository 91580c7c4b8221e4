"""A session's subscriptions to live LSL EMG streams: the rows behind the stream routes.

One recording per stream: a stream is identified by what it resolved to (its source id,
else its name), so a subscription by name and one by name and source id are the same
stream, and a second active subscription to it anywhere is refused. Resolving the stream
and checking its channels against the montage happen before (`backend.emg.live`); the
inlets themselves are started and stopped by `backend.emg.live.EmgLab`.
"""

from __future__ import annotations

import threading

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError
from backend.db import audit
from backend.db.emg import EmgMontage, EmgStream
from backend.db.models import User
from backend.db.sessions import session_row, study_of_session
from backend.schemas.emg import EmgStreamIn

#: Serialises the duplicate check and the insert of a subscription (held for one query
#: and one commit), so concurrent requests cannot both pass the check.
_SUBSCRIBE_LOCK = threading.Lock()


def session_streams(db: Session, session_id: int) -> list[EmgStream]:
    """The session's subscriptions, oldest first."""
    return list(db.scalars(select(EmgStream).where(EmgStream.session_id == session_id)
                           .order_by(EmgStream.id)))


def session_stream(db: Session, session_id: int, stream_id: int) -> EmgStream:
    """One subscription of the session; `NotFoundError` otherwise."""
    return session_row(db, EmgStream, session_id, stream_id, "EMG subscription")


def _same_stream(other: EmgStream, name: str, source_id: str) -> bool:
    """Whether an existing subscription records the stream resolved as name/source id."""
    if source_id and other.source_id:
        return other.source_id == source_id
    return other.name == name


def _already_recorded(db: Session, other: EmgStream, session_id: int, key: str
                      ) -> ConflictError:
    """The refusal for a stream already recorded; another study's session stays
    unnamed."""
    if study_of_session(db, other.session_id) == study_of_session(db, session_id):
        where = f"session {other.session_id} of this study"
    else:
        where = "a session of another study"
    return ConflictError("source_id", f"{where} already records the LSL stream {key!r}; one "
                         "recording per stream: unsubscribe it there first")


def add(db: Session, user: User, session_id: int, body: EmgStreamIn, montage: EmgMontage,
        resolved_name: str, resolved_sid: str) -> EmgStream:
    """Store an active subscription to the stream as it resolved; a conflict if an
    active subscription already records it. Commits."""
    key = body.source_id or body.name
    with _SUBSCRIBE_LOCK:
        for other in db.scalars(select(EmgStream).where(EmgStream.active)):
            if _same_stream(other, resolved_name, resolved_sid):
                raise _already_recorded(db, other, session_id, key)
        sub = EmgStream(session_id=session_id, name=body.name,
                        source_id=body.source_id or resolved_sid, montage_id=montage.id,
                        ignored_labels=body.ignore_labels, active=True, error="")
        db.add(sub)
        db.flush()
        audit.record(db, user, "create", "emg_stream", sub.id, body.model_dump())
        db.commit()
    return sub


def deactivate(db: Session, user: User, sub: EmgStream) -> EmgStream:
    """Mark the subscription inactive once its inlet has stopped (the inlet may have
    written an error to the row from its own session, so it is read again first).
    Commits."""
    db.refresh(sub)
    sub.active = False
    audit.record(db, user, "delete", "emg_stream", sub.id, {})
    db.commit()
    return sub
