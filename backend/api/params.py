"""Path and query parameter types. Ids are bounded to 32-bit integers: an id beyond what
any database column holds is a 404 or 422, never a driver overflow (a 500)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Path

from backend.schemas.fields import MAX_ID

__all__ = ["MAX_ID"]

StudyId = Annotated[int, Path(ge=1, le=MAX_ID, description="study id")]
ParticipantId = Annotated[int, Path(ge=1, le=MAX_ID, description="participant id")]
SessionId = Annotated[int, Path(ge=1, le=MAX_ID, description="session id")]
HardwareProfileId = Annotated[int, Path(ge=1, le=MAX_ID, description="hardware profile id")]
