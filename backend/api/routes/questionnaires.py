"""Questionnaire instruments, participant links, and the scored responses.

Instruments are definitions (built-in or imported); a link asks one participant for
some forms, each about a blinded condition; responses come back through the link
(`participant_forms`) and are listed here unblinded for the experimenter.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Annotated

from fastapi import APIRouter, Path, Request
from sqlalchemy import select

from backend.api.deps import CurrentUser, SessionDep, access
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    INVALID,
    NOT_FOUND,
    commit_or_conflict,
    conflict,
    invalid,
    invalid_many,
    not_found,
    one_or_404,
)
from backend.api.params import ParticipantId
from backend.core.security import new_token, token_digest
from backend.db.models import (
    Participant,
    ParticipantLink,
    QuestionnaireInstrument,
    QuestionnaireResponse,
)
from backend.questionnaires.definition import (
    KEY_PATTERN,
    VERSION_PATTERN,
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
from backend.study import audit
from backend.study.access import may_unblind
from backend.study.blinding import labels_of

router = APIRouter(tags=["questionnaires"], responses=AUTH_RESPONSES)


def summary(row: QuestionnaireInstrument) -> InstrumentSummary:
    """The list view of an instrument, wording provenance included."""
    prov = row.definition.get("provenance", {})
    return InstrumentSummary(id=row.id, key=row.key, version=row.version, title=row.title,
                             built_in=row.built_in, wording=prov.get("wording", "study"),
                             wording_note=prov.get("note", ""), created_at=row.created_at)


def find_instrument(db: SessionDep, key: str, version: str | None
                    ) -> QuestionnaireInstrument | None:
    """An instrument by key and version, or the newest version of `key`."""
    q = select(QuestionnaireInstrument).where(QuestionnaireInstrument.key == key)
    if version is not None:
        q = q.where(QuestionnaireInstrument.version == version)
    return db.scalars(q.order_by(QuestionnaireInstrument.id.desc())).first()


def link_out(link: ParticipantLink) -> LinkOut:
    """A link without its token."""
    return LinkOut(id=link.id, participant_id=link.participant_id,
                   forms_due=[FormDue(**f) for f in link.forms_due],
                   preference_due=link.preference_due, created_at=link.created_at,
                   expires_at=link.expires_at, used_at=link.used_at)


@router.get("/api/instruments", response_model=list[InstrumentSummary])
def list_instruments(user: CurrentUser, db: SessionDep) -> list[InstrumentSummary]:
    """Every instrument and version; `wording` tells whose item texts they are."""
    rows = db.scalars(select(QuestionnaireInstrument)
                      .order_by(QuestionnaireInstrument.key, QuestionnaireInstrument.id))
    return [summary(r) for r in rows]


@router.post("/api/instruments", response_model=InstrumentOut, status_code=201,
             responses={**BODY, **CONFLICT}, openapi_extra=access("experimenter"))
def import_instrument(definition: InstrumentDefinition, user: CurrentUser, db: SessionDep
                      ) -> InstrumentOut:
    """Import a study's own definition file (the JSON body). It is validated like the
    built-ins; 409 if the key and version exist (add a new version instead)."""
    if find_instrument(db, definition.key, definition.version) is not None:
        conflict("version", f"instrument {definition.key!r} version {definition.version!r} "
                 "exists; import it under a new version")
    data = definition.model_dump(mode="json")
    row = QuestionnaireInstrument(key=definition.key, version=definition.version,
                                  title=definition.title, definition=data, built_in=False,
                                  created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "import", "instrument", row.id,
                 {"key": definition.key, "version": definition.version})
    commit_or_conflict(db, "version", "this key and version exist")
    return InstrumentOut(**summary(row).model_dump(), definition=definition)


@router.get("/api/instruments/{key}/{version}", response_model=InstrumentOut,
            responses={**NOT_FOUND, **INVALID})
def get_instrument(key: Annotated[str, Path(pattern=KEY_PATTERN)],
                   version: Annotated[str, Path(pattern=VERSION_PATTERN)],
                   user: CurrentUser, db: SessionDep) -> InstrumentOut:
    """One instrument version with its full definition."""
    row = find_instrument(db, key, version)
    if row is None:
        not_found("instrument", f"{key} {version}")
    return InstrumentOut(**summary(row).model_dump(),
                         definition=InstrumentDefinition.model_validate(row.definition))


@router.post("/api/participants/{participant_id}/links", response_model=LinkCreated,
             status_code=201, responses={**NOT_FOUND, **BODY})
def create_link(participant_id: ParticipantId, body: LinkIn, request: Request,
                user: CurrentUser, db: SessionDep) -> LinkCreated:
    """A single-use link for the participant to fill in the forms due (and, if asked,
    say which condition they preferred). The token is in this answer only."""
    one_or_404(db, Participant, participant_id, "participant")
    if not body.forms and not body.preference:
        invalid(["body", "forms"], "a link must ask for at least one form or the preference")
    labels = labels_of(db, participant_id)
    problems: list[tuple[list[str | int], str]] = []
    due: list[dict[str, str | None]] = []
    for i, form in enumerate(body.forms):
        inst = find_instrument(db, form.instrument_key, form.instrument_version)
        if inst is None:
            what = form.instrument_key + (f" {form.instrument_version}"
                                          if form.instrument_version else "")
            problems.append((["body", "forms", i, "instrument_key"],
                             f"no instrument {what}"))
            continue
        if form.condition_label is not None and form.condition_label not in labels:
            problems.append((["body", "forms", i, "condition_label"],
                             f"{form.condition_label!r} is not a condition of this participant"
                             f" (known: {sorted(labels)})"))
            continue
        entry = {"instrument_key": inst.key, "instrument_version": inst.version,
                 "condition_label": form.condition_label}
        if entry in due:
            problems.append((["body", "forms", i], "the same form is already due on this link"))
            continue
        due.append(entry)
    if body.preference and not labels:
        problems.append((["body", "preference"], "the participant has no blinded conditions "
                         "to choose from (POST .../conditions first)"))
    if problems:
        invalid_many(problems)
    token = new_token()
    now = datetime.now(UTC)
    link = ParticipantLink(participant_id=participant_id, token_hash=token_digest(token),
                           forms_due=due, preference_due=body.preference, created_by=user.id,
                           created_at=now, expires_at=now + timedelta(hours=body.valid_hours))
    db.add(link)
    db.flush()
    audit.record(db, user, "create", "participant_link", link.id,
                 {"participant_id": participant_id, "forms_due": due,
                  "preference_due": body.preference})
    commit_or_conflict(db, "token", "token collision, try again")
    base = str(request.base_url).rstrip("/")
    return LinkCreated(**link_out(link).model_dump(), token=token,
                       url=f"{base}/forms/{token}", api_path=f"/api/participant-forms/{token}")


@router.get("/api/participants/{participant_id}/links", response_model=list[LinkOut],
            responses={**NOT_FOUND, **INVALID})
def list_links(participant_id: ParticipantId, user: CurrentUser, db: SessionDep
               ) -> list[LinkOut]:
    """The participant's links (without tokens) and whether they were used."""
    one_or_404(db, Participant, participant_id, "participant")
    return [link_out(x) for x in db.scalars(select(ParticipantLink).where(
        ParticipantLink.participant_id == participant_id).order_by(ParticipantLink.id))]


@router.get("/api/participants/{participant_id}/responses",
            response_model=list[ResponseOut], responses={**NOT_FOUND, **INVALID})
def list_responses(participant_id: ParticipantId, request: Request, user: CurrentUser,
                   db: SessionDep) -> list[ResponseOut]:
    """The participant's scored responses, unblinded (`controller`) for the study's
    owners; `controller` is null for other roles."""
    one_or_404(db, Participant, participant_id, "participant")
    labels = labels_of(db, participant_id) if may_unblind(request.state) else {}
    rows = db.scalars(select(QuestionnaireResponse).where(
        QuestionnaireResponse.participant_id == participant_id)
        .order_by(QuestionnaireResponse.id))
    return [ResponseOut(
        id=r.id, participant_id=r.participant_id, instrument_key=r.instrument_key,
        instrument_version=r.instrument_version, condition_label=r.condition_label,
        controller=labels.get(r.condition_label) if r.condition_label else None,
        answers=r.answers, score=r.score, subscale_scores=r.subscale_scores,
        submitted_at=r.submitted_at) for r in rows]
