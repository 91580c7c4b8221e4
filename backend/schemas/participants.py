"""Participant and blinding-key bodies."""

from __future__ import annotations

from datetime import date
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from backend.schemas.fields import Code, Label, PlainText, UtcDatetime

Sex = Literal["female", "male", "other", "not_stated"]

# Plausible adult ranges: a value outside is far more likely a unit slip (cm for m,
# lb for kg) than a real participant.


def _not_future(v: date | None) -> date | None:
    if v is not None and v > date.today():
        raise ValueError("consent_date lies in the future")
    if v is not None and v.year < 2000:
        raise ValueError("consent_date before 2000 is not plausible")
    return v


#: A site's short name ("Leuven", "site-2").
SiteName = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9 ._-]{0,63}$")]
#: A consent document version ("1.0", "2026-03").
ConsentVersion = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]{0,31}$")]


class WithdrawalOut(BaseModel):
    """What withdrawal did: "erased" (nothing is left) or "excluded" (kept, marked)."""

    participant_id: int
    outcome: Literal["erased", "excluded"]


class ParticipantIn(BaseModel):
    """A new participant; the code is unique within the study."""

    model_config = ConfigDict(extra="forbid")

    code: Code
    age: int | None = Field(default=None, ge=16, le=100, description="years")
    sex: Sex | None = None
    height_m: float | None = Field(default=None, ge=1.0, le=2.5,
                                   description="metres (not cm)")
    mass_kg: float | None = Field(default=None, ge=30.0, le=250.0, description="kilograms")
    consent_date: date | None = None
    notes: PlainText = ""
    #: The recruiting site (a site-limited member's own site is used when absent).
    site: SiteName | None = None
    #: The consent document version agreed to (one of the study's versions).
    consent_version: ConsentVersion | None = None

    _consent = field_validator("consent_date")(_not_future)


class ParticipantUpdate(BaseModel):
    """Fields to change; absent fields stay, `null` clears an optional one."""

    model_config = ConfigDict(extra="forbid")

    code: Code | None = None
    age: int | None = Field(default=None, ge=16, le=100)
    sex: Sex | None = None
    height_m: float | None = Field(default=None, ge=1.0, le=2.5)
    mass_kg: float | None = Field(default=None, ge=30.0, le=250.0)
    consent_date: date | None = None
    notes: PlainText | None = None
    site: SiteName | None = None
    consent_version: ConsentVersion | None = None

    _consent = field_validator("consent_date")(_not_future)


class ParticipantOut(BaseModel):
    """A participant."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    study_id: int
    code: str
    age: int | None
    sex: str | None
    height_m: float | None
    mass_kg: float | None
    consent_date: date | None
    notes: str
    created_at: UtcDatetime
    site: str | None = None
    consent_version: str | None = None
    withdrawn_at: UtcDatetime | None = None


class ConditionIn(BaseModel):
    """Blind a controller behind a label for this participant."""

    model_config = ConfigDict(extra="forbid")

    label: Label
    controller: str = Field(min_length=1, max_length=32,
                            description="controller name: none, umc, eumc or pec")


class ConditionOut(BaseModel):
    """One entry of the blinding key (experimenters only)."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    participant_id: int
    label: str
    #: The controller behind the label: the blinding key, shown to owners only.
    controller: str | None
    created_at: UtcDatetime
