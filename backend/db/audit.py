"""The audit log: who created or changed what.

`record` adds the entry to the caller's session, so it commits or rolls back together
with the change it describes.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db.models import AuditEntry, User


def record(session: Session, actor: User | str, action: str, entity: str,
           entity_id: int | str | None, details: dict[str, Any] | None = None) -> AuditEntry:
    """Add an audit entry; `actor` is the logged-in user or a description such as
    "participant link 7"."""
    entry = AuditEntry(
        user_id=actor.id if isinstance(actor, User) else None,
        actor=actor.username if isinstance(actor, User) else actor,
        action=action, entity=entity,
        entity_id=None if entity_id is None else str(entity_id),
        details=details or {},
    )
    session.add(entry)
    return entry


def entries(session: Session, entity: str | None, entity_id: str | None, limit: int,
            offset: int) -> list[AuditEntry]:
    """The log newest first, optionally of one entity (and id): what the admin page
    pages through."""
    q = select(AuditEntry)
    if entity is not None:
        q = q.where(AuditEntry.entity == entity)
    if entity_id is not None:
        q = q.where(AuditEntry.entity_id == entity_id)
    return list(session.scalars(q.order_by(AuditEntry.id.desc()).limit(limit).offset(offset)))
