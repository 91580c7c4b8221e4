"""Path and query parameter types. Ids are bounded to 32-bit integers: an id beyond what
any database column holds is a 404 or 422, never a driver overflow (a 500)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Path

from backend.schemas.fields import MAX_ID

__all__ = ["MAX_ID", "path_id"]

#: Digits in the largest id: a longer string is no id, whatever its value (and int()
#: refuses strings beyond 4,300 digits with a ValueError, a 500 if it escaped).
MAX_ID_DIGITS = len(str(MAX_ID))


def path_id(raw: str) -> int | None:
    """The id a raw path segment names, or None if it is not a plain decimal id in
    1..MAX_ID. The length is bounded before int() so no string can make int() raise."""
    digits = raw.lstrip("0")
    if not raw.isascii() or not raw.isdigit() or len(digits) > MAX_ID_DIGITS:
        return None
    value = int(digits or "0")
    return value if 1 <= value <= MAX_ID else None

StudyId = Annotated[int, Path(ge=1, le=MAX_ID, description="study id")]
ParticipantId = Annotated[int, Path(ge=1, le=MAX_ID, description="participant id")]
SessionId = Annotated[int, Path(ge=1, le=MAX_ID, description="session id")]
HardwareProfileId = Annotated[int, Path(ge=1, le=MAX_ID, description="hardware profile id")]
