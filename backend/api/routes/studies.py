"""Studies."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Request, Response
from fastapi import Path as PathParam

from backend.api.deps import CurrentUser, EngineDep, RuntimeDep, SessionDep, SiteDep, access
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    INVALID,
    NOT_FOUND,
)
from backend.api.params import StudyId
from backend.db.models import ConsentDocument, Study
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
from backend.study import studies

router = APIRouter(prefix="/api/studies", tags=["studies"], responses=AUTH_RESPONSES)


@router.get("", response_model=list[StudyOut], openapi_extra=access("login"))
def list_studies(user: CurrentUser, db: SessionDep) -> list[Study]:
    """The studies the caller is a member of (an admin: every study), oldest first."""
    return studies.visible(db, user)


@router.post("", response_model=StudyOut, status_code=201,
             responses={**BODY, **CONFLICT}, openapi_extra=access("login"))
def create_study(body: StudyIn, user: CurrentUser, db: SessionDep) -> Study:
    """Create a study; its creator is its owner. 409 if the name is taken."""
    return studies.create(db, user, body)


@router.get("/{study_id}", response_model=StudyOut, responses={**NOT_FOUND, **INVALID})
def get_study(study_id: StudyId, user: CurrentUser, db: SessionDep) -> Study:
    """One study."""
    return studies.get(db, study_id)


@router.patch("/{study_id}", response_model=StudyOut,
              responses={**NOT_FOUND, **BODY, **CONFLICT}, openapi_extra=access("owner"))
def update_study(study_id: StudyId, body: StudyUpdate, user: CurrentUser, db: SessionDep
                 ) -> Study:
    """Rename a study or change its description, withdrawal policy or dataset
    description (authors, licence, institution: what its exports say about the data)."""
    return studies.update(db, user, study_id, body)


# --- Members (owner) -------------------------------------------------------------------


@router.get("/{study_id}/members", response_model=list[MemberOut],
            responses={**NOT_FOUND, **INVALID})
def list_members(study_id: StudyId, db: SessionDep) -> list[MemberOut]:
    """Who has which role in the study (and which site, if limited)."""
    return studies.members(db, study_id)


@router.put("/{study_id}/members", response_model=list[MemberOut],
            responses={**NOT_FOUND, **BODY}, openapi_extra=access("owner"))
def set_member(study_id: StudyId, body: MemberIn, user: CurrentUser, db: SessionDep
               ) -> list[MemberOut]:
    """Give an account a role in the study (or change it, or its site)."""
    return studies.set_member(db, user, study_id, body)


@router.delete("/{study_id}/members/{username}", status_code=204,
               responses={**NOT_FOUND, **INVALID}, openapi_extra=access("owner"))
def remove_member(study_id: StudyId,
                  username: Annotated[str, PathParam(max_length=64,
                                                     pattern=r"^[A-Za-z0-9._-]+$")],
                  user: CurrentUser, db: SessionDep) -> Response:
    """Take an account's role in the study away (its creator stays owner)."""
    studies.remove_member(db, user, study_id, username)
    return Response(status_code=204)


# --- Consent documents -----------------------------------------------------------------


@router.get("/{study_id}/consent", response_model=list[ConsentOut],
            responses={**NOT_FOUND, **INVALID})
def list_consent(study_id: StudyId, db: SessionDep) -> list[ConsentDocument]:
    """The study's consent document versions, oldest first."""
    return studies.consent_documents(db, study_id)


@router.post("/{study_id}/consent", response_model=ConsentOut, status_code=201,
             responses={**NOT_FOUND, **BODY, **CONFLICT}, openapi_extra=access("owner"))
def add_consent(study_id: StudyId, body: ConsentIn, user: CurrentUser, db: SessionDep
                ) -> ConsentDocument:
    """Add a consent document version (versions are never edited)."""
    return studies.add_consent(db, user, study_id, body)


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
    studies.record_export(db, user, study_id, "export_deidentified", {"bytes": len(data)})
    return Response(data, media_type="application/zip", headers={
        "Content-Disposition": f'attachment; filename="study-{study_id}-deidentified.zip"'})
