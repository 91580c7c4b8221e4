"""The audit log, newest first."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from backend.api.deps import CurrentUser, SessionDep, access
from backend.api.errors import AUTH_RESPONSES, INVALID
from backend.db import audit
from backend.db.models import AuditEntry
from backend.schemas.audit import AuditOut

router = APIRouter(prefix="/api/audit", tags=["audit"], responses={**AUTH_RESPONSES, **INVALID})


@router.get("", response_model=list[AuditOut], openapi_extra=access("admin"))
def list_audit(
    user: CurrentUser,
    db: SessionDep,
    entity: Annotated[str | None, Query(max_length=64, pattern=r"^[a-z_]+$",
                                                description="e.g. participant")] = None,
    entity_id: Annotated[str | None, Query(max_length=64, pattern=r"^[A-Za-z0-9 ._-]+$")] = None,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
    offset: Annotated[int, Query(ge=0, le=1_000_000)] = 0,
) -> list[AuditEntry]:
    """Who created or changed what; filter by entity and id."""
    return audit.entries(db, entity, entity_id, limit, offset)
