"""Committing a service's writes: the one place a unique constraint that a concurrent
request won becomes a refusal that names the field (the checks before a write cannot
see another transaction's row)."""

from __future__ import annotations

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError


def commit_or_conflict(db: Session, field: str, problem: str) -> None:
    """Commit; an `IntegrityError` rolls back and is a `ConflictError(field, problem)`."""
    try:
        db.commit()
    except IntegrityError as exc:
        db.rollback()
        raise ConflictError(field, problem) from exc
