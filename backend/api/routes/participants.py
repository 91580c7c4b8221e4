"""Participants of a study, and each participant's blinding key."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.encoders import jsonable_encoder
from sqlalchemy import select

from backend import audit, withdrawal
from backend.access import Grant, may_unblind
from backend.api.deps import CurrentUser, SessionDep, access
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    NOT_FOUND,
    commit_or_conflict,
    conflict,
    invalid,
    one_or_404,
)
from backend.api.params import ParticipantId, StudyId
from backend.db.models import ConditionLabel, ConsentDocument, Participant, Study
from backend.schemas.participants import (
    ConditionIn,
    ConditionOut,
    ParticipantIn,
    ParticipantOut,
    ParticipantUpdate,
    WithdrawalOut,
)
from controller.factory import controller_names

router = APIRouter(tags=["participants"], responses={**AUTH_RESPONSES, **NOT_FOUND, **BODY})


def _code_taken(db: SessionDep, study_id: int, code: str, but: int | None = None) -> bool:
    found = db.scalars(select(Participant.id).where(
        Participant.study_id == study_id, Participant.code == code)).first()
    return found is not None and found != but


@router.get("/api/studies/{study_id}/participants", response_model=list[ParticipantOut])
def list_participants(study_id: StudyId, request: Request, user: CurrentUser,
                      db: SessionDep) -> list[Participant]:
    """The participants of a study, by code (a site-limited member: that site's)."""
    one_or_404(db, Study, study_id, "study")
    q = select(Participant).where(Participant.study_id == study_id)
    site = _site_of(request)
    if site is not None:
        q = q.where(Participant.site == site)
    return list(db.scalars(q.order_by(Participant.code)))


def _site_of(request: Request) -> str | None:
    """The site the caller is limited to (set by the access check), or None."""
    g: Grant | None = getattr(request.state, "grant", None)
    return g.site if g is not None else None


def _check_consent_version(db: SessionDep, study_id: int, version: str | None) -> None:
    if version is not None and db.scalars(select(ConsentDocument.id).where(
            ConsentDocument.study_id == study_id, ConsentDocument.version == version)
            ).first() is None:
        invalid(["body", "consent_version"], f"study {study_id} has no consent version "
                f"{version!r}")


@router.post("/api/studies/{study_id}/participants", response_model=ParticipantOut,
             status_code=201, responses=CONFLICT)
def create_participant(study_id: StudyId, body: ParticipantIn, request: Request,
                       user: CurrentUser, db: SessionDep) -> Participant:
    """Enrol a participant under a pseudonymous code; 409 if the code exists in the
    study. A site-limited member enrols into their own site only."""
    one_or_404(db, Study, study_id, "study")
    site = _site_of(request)
    if site is not None:
        if body.site not in (None, site):
            invalid(["body", "site"], f"you may enrol into your site {site!r} only")
        body = body.model_copy(update={"site": site})
    _check_consent_version(db, study_id, body.consent_version)
    if _code_taken(db, study_id, body.code):
        conflict("code", f"participant {body.code!r} exists in study {study_id}")
    p = Participant(study_id=study_id, **body.model_dump())
    db.add(p)
    db.flush()
    audit.record(db, user, "create", "participant", p.id, body.model_dump(mode="json"))
    commit_or_conflict(db, "code", f"participant {body.code!r} exists in study {study_id}")
    return p


@router.get("/api/participants/{participant_id}", response_model=ParticipantOut)
def get_participant(participant_id: ParticipantId, user: CurrentUser, db: SessionDep
                    ) -> Participant:
    """One participant."""
    return one_or_404(db, Participant, participant_id, "participant")


@router.patch("/api/participants/{participant_id}", response_model=ParticipantOut,
              responses=CONFLICT)
def update_participant(participant_id: ParticipantId, body: ParticipantUpdate,
                       request: Request, user: CurrentUser, db: SessionDep) -> Participant:
    """Correct a participant's record; `null` clears an optional field."""
    p = one_or_404(db, Participant, participant_id, "participant")
    changes: dict[str, Any] = body.model_dump(exclude_unset=True)
    for required in ("code", "notes"):
        if required in changes and changes[required] is None:
            invalid(["body", required], "cannot be null")
    site = _site_of(request)
    if site is not None and changes.get("site", site) != site:
        invalid(["body", "site"], f"you may keep participants in your site {site!r} only")
    if "consent_version" in changes:
        _check_consent_version(db, p.study_id, changes["consent_version"])
    if "code" in changes and _code_taken(db, p.study_id, changes["code"], but=p.id):
        conflict("code", f"participant {changes['code']!r} exists in study {p.study_id}")
    before = {k: getattr(p, k) for k in changes}
    for field, value in changes.items():
        setattr(p, field, value)
    audit.record(db, user, "update", "participant", p.id, {
        "before": jsonable_encoder(before),
        "after": body.model_dump(mode="json", exclude_unset=True)})
    commit_or_conflict(db, "code", "this code exists in the study")
    return p


@router.get("/api/participants/{participant_id}/conditions",
            response_model=list[ConditionOut])
def list_conditions(participant_id: ParticipantId, request: Request, user: CurrentUser,
                    db: SessionDep) -> list[ConditionOut]:
    """The participant's blinded labels; the blinding key (which controller each label
    stands for) only for the study's owners, `null` for everyone else."""
    one_or_404(db, Participant, participant_id, "participant")
    rows = db.scalars(select(ConditionLabel).where(
        ConditionLabel.participant_id == participant_id).order_by(ConditionLabel.label))
    unblind = may_unblind(request.state)
    return [ConditionOut.model_validate(c).model_copy(
        update={} if unblind else {"controller": None}) for c in rows]


@router.post("/api/participants/{participant_id}/conditions", response_model=ConditionOut,
             status_code=201, responses=CONFLICT)
def add_condition(participant_id: ParticipantId, body: ConditionIn, user: CurrentUser,
                  db: SessionDep) -> ConditionLabel:
    """Blind a controller behind a label; 409 if the label or controller already has an
    entry for this participant (a key never changes once forms may use it)."""
    one_or_404(db, Participant, participant_id, "participant")
    if body.controller not in controller_names():
        invalid(["body", "controller"],
                f"unknown controller {body.controller!r}; one of {list(controller_names())}")
    existing = db.scalars(select(ConditionLabel).where(
        ConditionLabel.participant_id == participant_id)).all()
    if any(c.label == body.label for c in existing):
        conflict("label", f"label {body.label!r} is already used for this participant")
    if any(c.controller == body.controller for c in existing):
        conflict("controller", f"{body.controller!r} already has a label for this participant")
    c = ConditionLabel(participant_id=participant_id, label=body.label,
                       controller=body.controller)
    db.add(c)
    db.flush()
    audit.record(db, user, "create", "condition_label", c.id,
                 {"participant_id": participant_id, **body.model_dump()})
    commit_or_conflict(db, "label", "this label or controller is already used")
    return c


@router.post("/api/participants/{participant_id}/withdraw", response_model=WithdrawalOut,
             openapi_extra=access("owner"))
def withdraw(participant_id: ParticipantId, user: CurrentUser, db: SessionDep
             ) -> WithdrawalOut:
    """A participant withdraws: their data is erased, or (when the study's protocol
    says "exclude") kept, marked withdrawn and left out of results and exports. The
    audit entry names the participant id only, never the erased data."""
    p = one_or_404(db, Participant, participant_id, "participant")
    outcome = withdrawal.withdraw(db, p, user)
    db.commit()
    return WithdrawalOut(participant_id=participant_id, outcome=outcome)
