"""Study bodies."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from backend.schemas.fields import Name, PlainText, UtcDatetime


class StudyIn(BaseModel):
    """A new study; the name is unique."""

    model_config = ConfigDict(extra="forbid")

    name: Name
    description: PlainText = ""


class StudyUpdate(BaseModel):
    """Fields to change; absent fields stay as they are."""

    model_config = ConfigDict(extra="forbid")

    name: Name | None = None
    description: PlainText | None = None


class StudyOut(BaseModel):
    """A study."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    description: str
    created_by: int | None
    created_at: UtcDatetime
