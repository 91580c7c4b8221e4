"""The blinding key: participants see condition labels, the record maps them to
controllers. Everything that unblinds goes through here."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db.models import ConditionLabel


def labels_of(db: Session, participant_id: int) -> dict[str, str]:
    """The participant's blinding key: label -> controller."""
    return {c.label: c.controller for c in db.scalars(select(ConditionLabel).where(
        ConditionLabel.participant_id == participant_id))}
