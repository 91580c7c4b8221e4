"""What the lab keeps per study and session: the study's marker buttons, the session's
markers, its subscriptions to other software's LSL marker streams and its attached XDF
files. The queries and writes behind the lab's routes (which parse, authorise and
call); the live side (inlets, outlets) stays with `backend.lab.hub.Lab`."""

from __future__ import annotations

import hashlib
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session, defer

from backend.core.errors import ConflictError, NotFoundError
from backend.db import audit
from backend.db.lab import Marker, MarkerStream, StudyMarkerLabels, XdfAttachment
from backend.db.models import User
from backend.schemas.lab import MarkerStreamIn


def set_marker_labels(db: Session, user: User, study_id: int, labels: list[str]) -> None:
    """Replace the study's marker buttons."""
    row = db.get(StudyMarkerLabels, study_id)
    if row is None:
        db.add(StudyMarkerLabels(study_id=study_id, labels=labels))
    else:
        row.labels = labels
        row.updated_at = datetime.now(UTC)
    audit.record(db, user, "update", "marker_labels", study_id, {"labels": labels})
    db.commit()


def session_markers(db: Session, session_id: int) -> list[Marker]:
    """The session's markers in the order they were stored."""
    return list(db.scalars(select(Marker).where(Marker.session_id == session_id)
                           .order_by(Marker.id)))


def subscriptions(db: Session, session_id: int) -> list[MarkerStream]:
    """The session's subscriptions to marker streams, oldest first."""
    return list(db.scalars(select(MarkerStream).where(MarkerStream.session_id == session_id)
                           .order_by(MarkerStream.id)))


def subscribe(db: Session, user: User, session_id: int, body: MarkerStreamIn) -> MarkerStream:
    """A new active subscription; a conflict while another session listens to the same
    stream (one session at a time stores a stream's markers)."""
    key = body.source_id or body.name
    for other in db.scalars(select(MarkerStream).where(MarkerStream.active)):
        if (other.source_id or other.name) == key:
            raise ConflictError("source_id", f"session {other.session_id} already listens "
                                f"to {key}; unsubscribe it there first")
    sub = MarkerStream(session_id=session_id, name=body.name, source_id=body.source_id,
                       stream_type="Markers", hostname="", active=True)
    db.add(sub)
    db.flush()
    audit.record(db, user, "create", "marker_stream", sub.id, body.model_dump())
    db.commit()
    return sub


def subscription(db: Session, session_id: int, subscription_id: int) -> MarkerStream:
    """One of the session's subscriptions; `NotFoundError` otherwise."""
    sub = db.get(MarkerStream, subscription_id)
    if sub is None or sub.session_id != session_id:
        raise NotFoundError("marker stream subscription", subscription_id)
    return sub


def end_subscription(db: Session, user: User, sub: MarkerStream) -> None:
    """Mark the subscription inactive (the markers it stored stay)."""
    sub.active = False
    audit.record(db, user, "delete", "marker_stream", sub.id, {})
    db.commit()


def attach_xdf(db: Session, user: User, session_id: int, filename: str, data: bytes,
               streams: list[dict[str, Any]]) -> XdfAttachment:
    """Keep an XDF file whole with the summary of its aligned streams."""
    att = XdfAttachment(session_id=session_id, filename=filename[:255], size_bytes=len(data),
                        sha256=hashlib.sha256(data).hexdigest(), content=data,
                        streams=streams, created_by=user.id)
    db.add(att)
    db.flush()
    audit.record(db, user, "create", "xdf_attachment", att.id,
                 {"filename": att.filename, "sha256": att.sha256, "streams": len(streams)})
    db.commit()
    return att


def attachments(db: Session, session_id: int) -> list[XdfAttachment]:
    """The session's XDF attachments, summaries only (the files, up to
    `max_upload_bytes` each, are not read)."""
    return list(db.scalars(select(XdfAttachment).options(defer(XdfAttachment.content))
                           .where(XdfAttachment.session_id == session_id)
                           .order_by(XdfAttachment.id)))


def attachment(db: Session, session_id: int, attachment_id: int) -> XdfAttachment:
    """One of the session's XDF attachments, file included; `NotFoundError` otherwise."""
    att = db.get(XdfAttachment, attachment_id)
    if att is None or att.session_id != session_id:
        raise NotFoundError("XDF attachment", attachment_id)
    return att
