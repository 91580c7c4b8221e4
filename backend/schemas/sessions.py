"""Session (participant visit) bodies."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from backend.schemas.fields import PlainText, UtcDatetime

#: `long_use`: the wearer works with the exoskeleton outside a trial plan; the
#: controller runs as a long-use trial (`backend.study.long_use`).
SessionKind = Literal["data_collection", "evaluation", "long_use"]


class SessionIn(BaseModel):
    """A new session: what it is for and how the exoskeleton was set."""

    model_config = ConfigDict(extra="forbid")

    kind: SessionKind
    precompression_pct: float = Field(ge=0.0, le=100.0,
                                      description="spring precompression, % of 22 mm")
    started_at: UtcDatetime | None = Field(default=None, description="default: now")
    notes: PlainText = ""


class SessionUpdate(BaseModel):
    """Fields to change; absent fields stay."""

    model_config = ConfigDict(extra="forbid")

    precompression_pct: float | None = Field(default=None, ge=0.0, le=100.0)
    notes: PlainText | None = None


class SessionOut(BaseModel):
    """A session."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    participant_id: int
    kind: str
    precompression_pct: float
    started_at: UtcDatetime
    notes: str
    created_at: UtcDatetime
    #: The hardware profile in effect when the session was created (None: none).
    hardware_profile_id: int | None = None
