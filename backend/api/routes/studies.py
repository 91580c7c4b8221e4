"""Studies."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Request, Response
from fastapi import Path as PathParam
from sqlalchemy import select

from backend.api.deps import CurrentUser, EngineDep, RuntimeDep, SessionDep, SiteDep, access
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    INVALID,
    NOT_FOUND,
    commit_or_conflict,
    conflict,
    invalid,
    not_found,
    one_or_404,
)
from backend.api.params import StudyId
from backend.db import audit
from backend.db.models import ConsentDocument, Study, StudyMember, User
from backend.schemas.studies import (
    ConsentIn,
    ConsentOut,
    MemberIn,
    MemberOut,
    StudyIn,
    StudyOut,
    StudyUpdate,
)
from backend.study import access as access_rules

router = APIRouter(prefix="/api/studies", tags=["studies"], responses=AUTH_RESPONSES)


def _name_taken(db: SessionDep, name: str, but: int | None = None) -> bool:
    found = db.scalars(select(Study.id).where(Study.name == name)).first()
    return found is not None and found != but


@router.get("", response_model=list[StudyOut], openapi_extra=access("login"))
def list_studies(user: CurrentUser, db: SessionDep) -> list[Study]:
    """The studies the caller is a member of (an admin: every study), oldest first."""
    q = select(Study).order_by(Study.id)
    visible = access_rules.visible_study_ids(db, user)
    if visible is not None:
        q = q.where(Study.id.in_(visible))
    return list(db.scalars(q))


@router.post("", response_model=StudyOut, status_code=201,
             responses={**BODY, **CONFLICT}, openapi_extra=access("login"))
def create_study(body: StudyIn, user: CurrentUser, db: SessionDep) -> Study:
    """Create a study; its creator is its owner. 409 if the name is taken."""
    if _name_taken(db, body.name):
        conflict("name", f"a study named {body.name!r} exists")
    study = Study(name=body.name, description=body.description, created_by=user.id,
                  withdrawal_policy=body.withdrawal_policy,
                  dataset_info=body.dataset_info.model_dump(mode="json"))
    db.add(study)
    db.flush()
    db.add(StudyMember(study_id=study.id, user_id=user.id, role="owner"))
    audit.record(db, user, "create", "study", study.id, body.model_dump(mode="json"))
    commit_or_conflict(db, "name", f"a study named {body.name!r} exists")
    return study


@router.get("/{study_id}", response_model=StudyOut, responses={**NOT_FOUND, **INVALID})
def get_study(study_id: StudyId, user: CurrentUser, db: SessionDep) -> Study:
    """One study."""
    return one_or_404(db, Study, study_id, "study")


@router.patch("/{study_id}", response_model=StudyOut,
              responses={**NOT_FOUND, **BODY, **CONFLICT}, openapi_extra=access("owner"))
def update_study(study_id: StudyId, body: StudyUpdate, user: CurrentUser, db: SessionDep
                 ) -> Study:
    """Rename a study or change its description, withdrawal policy or dataset
    description (authors, licence, institution: what its exports say about the data)."""
    study = one_or_404(db, Study, study_id, "study")
    changes = body.model_dump(mode="json", exclude_unset=True, exclude_none=True)
    if "name" in changes and _name_taken(db, changes["name"], but=study.id):
        conflict("name", f"a study named {changes['name']!r} exists")
    for field, value in changes.items():
        setattr(study, field, value)
    audit.record(db, user, "update", "study", study.id, changes)
    commit_or_conflict(db, "name", "a study with this name exists")
    return study


# --- Members (owner) -------------------------------------------------------------------


def _members(db: SessionDep, study_id: int) -> list[MemberOut]:
    rows = db.execute(select(StudyMember, User.username).join(User, User.id == StudyMember.user_id)
                      .where(StudyMember.study_id == study_id).order_by(User.username))
    return [MemberOut(user_id=m.user_id, username=name, role=m.role, site=m.site)
            for m, name in rows]


@router.get("/{study_id}/members", response_model=list[MemberOut],
            responses={**NOT_FOUND, **INVALID})
def list_members(study_id: StudyId, db: SessionDep) -> list[MemberOut]:
    """Who has which role in the study (and which site, if limited)."""
    return _members(db, study_id)


@router.put("/{study_id}/members", response_model=list[MemberOut],
            responses={**NOT_FOUND, **BODY}, openapi_extra=access("owner"))
def set_member(study_id: StudyId, body: MemberIn, user: CurrentUser, db: SessionDep
               ) -> list[MemberOut]:
    """Give an account a role in the study (or change it, or its site)."""
    target = db.scalars(select(User).where(User.username == body.username)).first()
    if target is None:
        invalid(["body", "username"], f"no account named {body.username!r}")
    row = db.scalars(select(StudyMember).where(StudyMember.study_id == study_id,
                                               StudyMember.user_id == target.id)).first()
    if row is None:
        row = StudyMember(study_id=study_id, user_id=target.id, role=body.role, site=body.site)
        db.add(row)
    else:
        row.role, row.site = body.role, body.site
    audit.record(db, user, "set_member", "study", study_id, body.model_dump())
    commit_or_conflict(db, "username", "is already a member")
    return _members(db, study_id)


@router.delete("/{study_id}/members/{username}", status_code=204,
               responses={**NOT_FOUND, **INVALID}, openapi_extra=access("owner"))
def remove_member(study_id: StudyId,
                  username: Annotated[str, PathParam(max_length=64,
                                                     pattern=r"^[A-Za-z0-9._-]+$")],
                  user: CurrentUser, db: SessionDep) -> Response:
    """Take an account's role in the study away (its creator stays owner)."""
    target = db.scalars(select(User).where(User.username == username)).first()
    row = None if target is None else db.scalars(select(StudyMember).where(
        StudyMember.study_id == study_id, StudyMember.user_id == target.id)).first()
    if row is None:
        not_found("member", username)
    db.delete(row)
    audit.record(db, user, "remove_member", "study", study_id, {"username": username})
    db.commit()
    return Response(status_code=204)


# --- Consent documents -----------------------------------------------------------------


@router.get("/{study_id}/consent", response_model=list[ConsentOut],
            responses={**NOT_FOUND, **INVALID})
def list_consent(study_id: StudyId, db: SessionDep) -> list[ConsentDocument]:
    """The study's consent document versions, oldest first."""
    return list(db.scalars(select(ConsentDocument).where(ConsentDocument.study_id == study_id)
                           .order_by(ConsentDocument.id)))


@router.post("/{study_id}/consent", response_model=ConsentOut, status_code=201,
             responses={**NOT_FOUND, **BODY, **CONFLICT}, openapi_extra=access("owner"))
def add_consent(study_id: StudyId, body: ConsentIn, user: CurrentUser, db: SessionDep
                ) -> ConsentDocument:
    """Add a consent document version (versions are never edited)."""
    if db.scalars(select(ConsentDocument.id).where(
            ConsentDocument.study_id == study_id,
            ConsentDocument.version == body.version)).first() is not None:
        conflict("version", f"version {body.version!r} exists; add a new version instead")
    doc = ConsentDocument(study_id=study_id, version=body.version, text=body.text)
    db.add(doc)
    db.flush()
    audit.record(db, user, "create", "consent", doc.id, {"study_id": study_id,
                                                         "version": body.version})
    commit_or_conflict(db, "version", f"version {body.version!r} exists")
    return doc


@router.get("/{study_id}/export-deidentified.zip", response_class=Response,
            responses={**NOT_FOUND, **INVALID, 200: {
                "content": {"application/zip": {}},
                "description": "the export without identifiers, dates shifted"}},
            openapi_extra=access("experimenter"))
def export_deidentified(study_id: StudyId, engine: EngineDep, site: SiteDep,
                        runtime: RuntimeDep, user: CurrentUser, db: SessionDep,
                        request: Request) -> Response:
    """The study's export for sharing: participants re-coded, free text and account ids
    removed, ages above 89 as 90, dates shifted per participant; `data_dictionary.csv`
    says what was done to each column. The blinding key (`condition_labels.csv`
    `controller`) is filled in for the study's owner only. The full export needs the
    owner role."""
    from backend.analysis.export import study_zip

    runtime.recorder.flush()
    data = study_zip(engine, study_id, deidentified=True, site=site,
                     unblind=access_rules.may_unblind(request.state))
    audit.record(db, user, "export_deidentified", "study", study_id, {"bytes": len(data)})
    db.commit()
    return Response(data, media_type="application/zip", headers={
        "Content-Disposition": f'attachment; filename="study-{study_id}-deidentified.zip"'})
