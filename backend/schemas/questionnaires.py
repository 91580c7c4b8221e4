"""Questionnaire bodies: instruments, participant links, responses, preferences, and
what a participant's form shows (blinded labels only, never a controller name)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, StrictInt

from backend.questionnaires.definition import (
    KEY_PATTERN,
    VERSION_PATTERN,
    InstrumentDefinition,
    Item,
    Provenance,
    ResponseScale,
)
from backend.schemas.fields import Label, UtcDatetime


class InstrumentSummary(BaseModel):
    """An instrument in a list; `wording` says whose item texts these are."""

    id: int
    key: str
    version: str
    title: str
    built_in: bool
    study_id: int | None = Field(
        description="the study the instrument belongs to; null for a built-in")
    wording: str = Field(description="standard, project (ExoStudy's own) or study")
    wording_note: str
    created_at: UtcDatetime


class InstrumentOut(InstrumentSummary):
    """An instrument with its whole definition."""

    definition: InstrumentDefinition


class FormDueIn(BaseModel):
    """One form the participant is to fill in."""

    model_config = ConfigDict(extra="forbid")

    instrument_key: str = Field(pattern=KEY_PATTERN, examples=["sus"])
    instrument_version: str | None = Field(
        default=None, pattern=VERSION_PATTERN,
        description="default: the only version the study may use (422 if it has several)")
    condition_label: Label | None = Field(
        default=None, description="the blinded condition the form is about, if any")


class FormDue(BaseModel):
    """A form due, as stored on the link (`instrument_id`: the instrument row the link
    was made with, which is what the participant is shown)."""

    instrument_id: int | None = None
    instrument_key: str
    instrument_version: str
    condition_label: str | None


class LinkIn(BaseModel):
    """What the participant link asks for, and how long it stays valid."""

    model_config = ConfigDict(extra="forbid")

    forms: list[FormDueIn] = Field(default_factory=list, max_length=20)
    preference: bool = Field(default=False,
                             description="also ask which condition they preferred")
    valid_hours: int = Field(default=72, ge=1, le=24 * 60)


class LinkOut(BaseModel):
    """A participant link (its token is shown only once, at creation)."""

    id: int
    participant_id: int
    forms_due: list[FormDue]
    preference_due: bool
    created_at: UtcDatetime
    expires_at: UtcDatetime
    used_at: UtcDatetime | None


class LinkCreated(LinkOut):
    """A new link: give `url` (or `token`) to the participant; it is not stored."""

    token: str
    url: str = Field(description="the participant's form page")
    api_path: str = Field(description="the API path the form page uses")


class ResponseOut(BaseModel):
    """A scored response, unblinded for the experimenter (`controller`)."""

    id: int
    participant_id: int
    instrument_key: str
    instrument_version: str
    condition_label: str | None
    controller: str | None
    answers: dict[str, Any]
    score: float
    subscale_scores: dict[str, Any]
    submitted_at: UtcDatetime


class PreferenceOut(BaseModel):
    """A preference, unblinded for the experimenter."""

    id: int
    participant_id: int
    choice: str
    controller: str | None = Field(description="null for 'none' (no preference)")
    submitted_at: UtcDatetime


# --- What the participant sees --------------------------------------------------------


class FormView(BaseModel):
    """One form as the participant sees it."""

    index: int
    instrument_key: str
    instrument_version: str
    title: str
    instructions: str
    condition_label: str | None
    items: list[Item]
    scale: ResponseScale
    provenance: Provenance
    submitted: bool


class PreferenceView(BaseModel):
    """The preference question, if due: choose a label or "none"."""

    due: bool
    submitted: bool
    question: str = "Which controller did you prefer?"
    choices: list[str]


class ParticipantFormsOut(BaseModel):
    """Everything a participant link opens."""

    forms: list[FormView]
    preference: PreferenceView
    expires_at: UtcDatetime


class AnswersIn(BaseModel):
    """Answers to one form: item id -> value on the scale (null or absent: unanswered)."""

    model_config = ConfigDict(extra="forbid")

    # Strict: JSON `true` is not the answer 1, nor `3.0` or "3" an answer (pydantic's lax
    # mode would turn them into integers and score them).
    form: StrictInt = Field(ge=0, le=100, description="index of the form in `forms`")
    answers: dict[str, StrictInt | None] = Field(max_length=200)


class PreferenceIn(BaseModel):
    """The participant's preference: one of the offered choices."""

    model_config = ConfigDict(extra="forbid")

    choice: str = Field(min_length=1, max_length=16)


class SubmissionOut(BaseModel):
    """Receipt of a submission; the link closes when nothing is left."""

    accepted: bool = True
    forms_remaining: int
    preference_remaining: bool
    link_closed: bool
