"""Reading a study's model sets and utility sets: one implementation for both kinds (their
routes list, fetch and serve documents the same way), so a fix to one cannot miss the
other."""

from __future__ import annotations

from typing import Any, TypeVar

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, NotFoundError
from backend.db.evidence_tables import ModelSetRecord, UtilitySetRecord
from backend.db.models import Study

SetRecord = TypeVar("SetRecord", ModelSetRecord, UtilitySetRecord)
#: How a refusal names each kind.
NAMES: dict[type[Any], str] = {ModelSetRecord: "model set", UtilitySetRecord: "utility set"}


def study_sets(db: Session, kind: type[SetRecord], study_id: int) -> list[SetRecord]:
    """The study's sets of `kind`, oldest first; `NotFoundError` for an unknown study."""
    if db.get(Study, study_id) is None:
        raise NotFoundError("study", study_id)
    return list(db.scalars(select(kind).where(kind.study_id == study_id).order_by(kind.id)))


def one_set(db: Session, kind: type[SetRecord], set_id: int) -> SetRecord:
    """One set's record; `NotFoundError` naming the kind."""
    row = db.get(kind, set_id)
    if row is None:
        raise NotFoundError(NAMES[kind], set_id)
    return row


def ready_document(db: Session, kind: type[SetRecord], set_id: int) -> dict[str, Any]:
    """The set's versioned JSON document; `ConflictError` while it is not ready (pending,
    running or failed)."""
    row = one_set(db, kind, set_id)
    if row.document is None:
        raise ConflictError("status", f"{NAMES[kind]} {row.id} is {row.status}")
    document: dict[str, Any] = row.document
    return document
