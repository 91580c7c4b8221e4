"""What a participant link opens: the forms due, with blinded labels, and nothing else.

These routes take no login; the unguessable token in the path is the credential, and
everything they read or write is looked up through that token's link, so a token can
never reach another participant or an experimenter route.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path
from fastapi.responses import FileResponse

from backend.api.deps import SessionDep, SettingsDep, access
from backend.api.errors import BODY, CONFLICT, ErrorMessage, conflict, invalid, invalid_many
from backend.db.models import ParticipantLink, QuestionnaireInstrument
from backend.questionnaires.definition import InstrumentDefinition
from backend.questionnaires.scoring import AnswerError, score
from backend.schemas.questionnaires import (
    AnswersIn,
    FormView,
    ParticipantFormsOut,
    PreferenceIn,
    PreferenceView,
    SubmissionOut,
)
from backend.study import participant_links, questionnaire_answers
from backend.study.blinding import labels_of
from backend.study.participant_links import form_key

router = APIRouter(prefix="/api/participant-forms", tags=["participant forms"], responses={
    404: {"model": ErrorMessage, "description": "no such link"},
    410: {"model": ErrorMessage, "description": "the link expired or was used"},
    **BODY,
})

Token = Annotated[str, Path(min_length=16, max_length=128, pattern=r"^[A-Za-z0-9_-]+$",
                            description="the participant's link token")]

NO_PREFERENCE = "none"


def _aware(t: datetime) -> datetime:
    return t if t.tzinfo is not None else t.replace(tzinfo=UTC)


def open_link(db: SessionDep, token: str) -> ParticipantLink:
    """The link behind a token, if it is still open (404 unknown, 410 expired/used)."""
    link = participant_links.by_token(db, token)
    if link is None:
        raise HTTPException(404, "link does not exist")
    if link.used_at is not None:
        raise HTTPException(410, "this link has been used; ask the experimenter for a new one")
    if _aware(link.expires_at) <= datetime.now(UTC):
        raise HTTPException(410, "this link has expired; ask the experimenter for a new one")
    return link


def _choices(link: ParticipantLink, db: SessionDep) -> list[str]:
    return [*sorted(labels_of(db, link.participant_id)), NO_PREFERENCE]


def _instrument(db: SessionDep, link: ParticipantLink, form: dict[str, Any]
                ) -> QuestionnaireInstrument:
    """The instrument row the link pinned for this form (410 when it is gone)."""
    row = participant_links.instrument_of(db, link, form)
    if row is None:
        raise HTTPException(410, "a form of this link is no longer available; ask the "
                            "experimenter for a new link")
    return row


@router.get("/{token}", response_model=ParticipantFormsOut,
            openapi_extra=access("participant"))
def get_forms(token: Token, db: SessionDep) -> ParticipantFormsOut:
    """The forms due on this link, with blinded condition labels only."""
    link = open_link(db, token)
    done, pref_done = participant_links.submitted(db, link)
    forms = []
    for i, form in enumerate(link.forms_due):
        key, version, label = form_key(form)
        d = InstrumentDefinition.model_validate(_instrument(db, link, form).definition)
        forms.append(FormView(index=i, instrument_key=key, instrument_version=version,
                              title=d.title, instructions=d.instructions,
                              condition_label=label, items=d.items, scale=d.scale,
                              provenance=d.provenance, submitted=(key, version, label) in done))
    return ParticipantFormsOut(
        forms=forms, expires_at=link.expires_at,
        preference=PreferenceView(due=link.preference_due, submitted=pref_done,
                                  choices=_choices(link, db) if link.preference_due else []))


@router.post("/{token}/responses", response_model=SubmissionOut, status_code=201,
             responses=CONFLICT, openapi_extra=access("participant"))
def submit_answers(token: Token, body: AnswersIn, db: SessionDep) -> SubmissionOut:
    """Answer one form. The answers are validated against the instrument (every bad
    item is named), scored, and stored with the instrument version; 409 if this form
    was already answered."""
    link = open_link(db, token)
    if body.form >= len(link.forms_due):
        invalid(["body", "form"], f"this link has {len(link.forms_due)} form(s): "
                f"0..{len(link.forms_due) - 1}" if link.forms_due else "this link has no forms")
    key, version, label = form_key(link.forms_due[body.form])
    done, _ = participant_links.submitted(db, link)
    if (key, version, label) in done:
        conflict("form", "this form was already answered")
    inst = _instrument(db, link, link.forms_due[body.form])
    definition = InstrumentDefinition.model_validate(inst.definition)
    try:
        result = score(definition, body.answers)
    except AnswerError as exc:
        invalid_many([(["body", "answers", item], msg) for item, msg in exc.problems.items()])
    stored = {k: int(v) if float(v).is_integer() else v for k, v in result.answers.items()}
    return questionnaire_answers.store_response(db, link, body.form, inst, stored, result.score,
                                                result.subscales, list(result.substituted))


@router.post("/{token}/preference", response_model=SubmissionOut, status_code=201,
             responses=CONFLICT, openapi_extra=access("participant"))
def submit_preference(token: Token, body: PreferenceIn, db: SessionDep) -> SubmissionOut:
    """Say which condition was preferred: a label as shown, or "none"."""
    link = open_link(db, token)
    if not link.preference_due:
        conflict("preference", "this link does not ask for a preference")
    _, pref_done = participant_links.submitted(db, link)
    if pref_done:
        conflict("preference", "the preference was already given")
    choices = _choices(link, db)
    if body.choice not in choices:
        invalid(["body", "choice"], f"choose one of {choices}")
    return questionnaire_answers.store_preference(db, link, body.choice)


pages = APIRouter()


@pages.get("/forms/{token}", include_in_schema=False)
def form_page(token: Token, settings: SettingsDep) -> FileResponse:
    """The participant's form page; it reads its token from the address."""
    return FileResponse(settings.frontend_dir / "static" / "form.html")
