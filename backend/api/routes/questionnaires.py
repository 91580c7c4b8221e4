"""Questionnaire instruments, participant links, and the scored responses.

Instruments are definitions: built-in ones (global, never changed) or a study's own
(imported into that study and offered to its participants only); a link asks one participant for
some forms, each about a blinded condition; responses come back through the link
(`participant_forms`) and are listed here unblinded for the experimenter.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Request

from backend.api.deps import CurrentUser, SessionDep
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    INVALID,
    NOT_FOUND,
    invalid,
    not_found,
    one_or_404,
)
from backend.api.params import ParticipantId, StudyId
from backend.db.models import Participant, ParticipantLink, QuestionnaireInstrument, Study
from backend.questionnaires.catalog import built_in_keys
from backend.questionnaires.definition import (
    KEY_PATTERN,
    VERSION_PATTERN,
    ImportedInstrument,
    InstrumentDefinition,
)
from backend.schemas.questionnaires import (
    FormDue,
    InstrumentOut,
    InstrumentSummary,
    LinkCreated,
    LinkIn,
    LinkOut,
    ResponseOut,
)
from backend.study import instruments, participant_links, questionnaire_answers
from backend.study.access import may_unblind
from backend.study.blinding import labels_of

router = APIRouter(tags=["questionnaires"], responses=AUTH_RESPONSES)

InstrumentKey = Annotated[str, Path(pattern=KEY_PATTERN)]
InstrumentVersion = Annotated[str, Path(pattern=VERSION_PATTERN)]


def summary(row: QuestionnaireInstrument) -> InstrumentSummary:
    """The list view of an instrument, wording provenance included."""
    prov = row.definition.get("provenance", {})
    return InstrumentSummary(id=row.id, key=row.key, version=row.version, title=row.title,
                             built_in=row.built_in, study_id=row.study_id,
                             wording=prov.get("wording", "study"),
                             wording_note=prov.get("note", ""), created_at=row.created_at)


def link_out(link: ParticipantLink) -> LinkOut:
    """A link without its token."""
    return LinkOut(id=link.id, participant_id=link.participant_id,
                   forms_due=[FormDue(**f) for f in link.forms_due],
                   preference_due=link.preference_due, created_at=link.created_at,
                   expires_at=link.expires_at, used_at=link.used_at)


def _full(row: QuestionnaireInstrument) -> InstrumentOut:
    return InstrumentOut(**summary(row).model_dump(),
                         definition=InstrumentDefinition.model_validate(row.definition))


@router.get("/api/instruments", response_model=list[InstrumentSummary])
def list_instruments(user: CurrentUser, db: SessionDep) -> list[InstrumentSummary]:
    """The built-in instruments (a study's own ones: `/api/studies/{id}/instruments`);
    `wording` tells whose item texts they are."""
    return [summary(r) for r in instruments.of_study(db, None)]


@router.get("/api/instruments/{key}/{version}", response_model=InstrumentOut,
            responses={**NOT_FOUND, **INVALID})
def get_instrument(key: InstrumentKey, version: InstrumentVersion, user: CurrentUser,
                   db: SessionDep) -> InstrumentOut:
    """One built-in instrument version with its full definition."""
    row = instruments.find(db, None, key, version)
    if row is None:
        not_found("instrument", f"{key} {version}")
    return _full(row)


@router.get("/api/studies/{study_id}/instruments", response_model=list[InstrumentSummary],
            responses={**NOT_FOUND, **INVALID})
def list_study_instruments(study_id: StudyId, user: CurrentUser, db: SessionDep
                           ) -> list[InstrumentSummary]:
    """The instruments the study's links may use: the built-ins and the study's own."""
    one_or_404(db, Study, study_id, "study")
    return [summary(r) for r in instruments.of_study(db, study_id)]


@router.post("/api/studies/{study_id}/instruments", response_model=InstrumentOut,
             status_code=201, responses={**NOT_FOUND, **BODY, **CONFLICT})
def import_instrument(study_id: StudyId, definition: ImportedInstrument, user: CurrentUser,
                      db: SessionDep) -> InstrumentOut:
    """Import the study's own definition file (the JSON body); only this study's links
    can use it. It is validated like the built-ins, and its form must stay usable: at
    most 101 scale points, one label per point with its own words, at most 5,000 answer
    choices (items x points); the key of a built-in instrument is refused (422), and
    409 if the study has this key and version (add a new version)."""
    one_or_404(db, Study, study_id, "study")
    if definition.key in built_in_keys():
        invalid(["body", "key"], f"{definition.key!r} is a built-in instrument; a study's "
                "own instrument needs its own key (for example "
                f"{definition.key + '-' + 'study'!r})")
    row = instruments.add_to_study(db, user, study_id, definition.key, definition.version,
                                   definition.title, definition.model_dump(mode="json"))
    return InstrumentOut(**summary(row).model_dump(), definition=definition)


@router.get("/api/studies/{study_id}/instruments/{key}/{version}",
            response_model=InstrumentOut, responses={**NOT_FOUND, **INVALID})
def get_study_instrument(study_id: StudyId, key: InstrumentKey, version: InstrumentVersion,
                         user: CurrentUser, db: SessionDep) -> InstrumentOut:
    """One instrument version the study may use, with its full definition."""
    one_or_404(db, Study, study_id, "study")
    row = instruments.find(db, study_id, key, version)
    if row is None:
        not_found("instrument", f"{key} {version}")
    return _full(row)


@router.get("/api/participants/{participant_id}/instruments",
            response_model=list[InstrumentSummary], responses={**NOT_FOUND, **INVALID})
def list_participant_instruments(participant_id: ParticipantId, user: CurrentUser,
                                 db: SessionDep) -> list[InstrumentSummary]:
    """The instruments a link for this participant may ask for (the console's list)."""
    p = one_or_404(db, Participant, participant_id, "participant")
    return [summary(r) for r in instruments.of_study(db, p.study_id)]


@router.post("/api/participants/{participant_id}/links", response_model=LinkCreated,
             status_code=201, responses={**NOT_FOUND, **BODY})
def create_link(participant_id: ParticipantId, body: LinkIn, request: Request,
                user: CurrentUser, db: SessionDep) -> LinkCreated:
    """A single-use link for the participant to fill in the forms due (and, if asked,
    say which condition they preferred). Each form is pinned to one instrument row of
    the participant's study (or a built-in). The token is in this answer only."""
    participant = one_or_404(db, Participant, participant_id, "participant")
    link, token = participant_links.create(db, user, participant, body)
    base = str(request.base_url).rstrip("/")
    return LinkCreated(**link_out(link).model_dump(), token=token,
                       url=f"{base}/forms/{token}", api_path=f"/api/participant-forms/{token}")


@router.get("/api/participants/{participant_id}/links", response_model=list[LinkOut],
            responses={**NOT_FOUND, **INVALID})
def list_links(participant_id: ParticipantId, user: CurrentUser, db: SessionDep
               ) -> list[LinkOut]:
    """The participant's links (without tokens) and whether they were used."""
    one_or_404(db, Participant, participant_id, "participant")
    return [link_out(x) for x in participant_links.of_participant(db, participant_id)]


@router.get("/api/participants/{participant_id}/responses",
            response_model=list[ResponseOut], responses={**NOT_FOUND, **INVALID})
def list_responses(participant_id: ParticipantId, request: Request, user: CurrentUser,
                   db: SessionDep) -> list[ResponseOut]:
    """The participant's scored responses, unblinded (`controller`) for the study's
    owners; `controller` is null for other roles."""
    one_or_404(db, Participant, participant_id, "participant")
    labels = labels_of(db, participant_id) if may_unblind(request.state) else {}
    rows = questionnaire_answers.responses_of(db, participant_id)
    return [ResponseOut(
        id=r.id, participant_id=r.participant_id, instrument_key=r.instrument_key,
        instrument_version=r.instrument_version, condition_label=r.condition_label,
        controller=labels.get(r.condition_label) if r.condition_label else None,
        answers=r.answers, score=r.score, subscale_scores=r.subscale_scores,
        submitted_at=r.submitted_at) for r in rows]
