"""Audit log bodies."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict

from backend.schemas.fields import UtcDatetime


class AuditOut(BaseModel):
    """One audit entry."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    at: UtcDatetime
    user_id: int | None
    actor: str
    action: str
    entity: str
    entity_id: str | None
    details: dict[str, Any]
