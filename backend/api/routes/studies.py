"""Studies."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import select

from backend import audit
from backend.api.deps import CurrentUser, SessionDep
from backend.api.errors import (
    AUTH_RESPONSES,
    BODY,
    CONFLICT,
    INVALID,
    NOT_FOUND,
    commit_or_conflict,
    conflict,
    one_or_404,
)
from backend.api.params import StudyId
from backend.db.models import Study
from backend.schemas.studies import StudyIn, StudyOut, StudyUpdate

router = APIRouter(prefix="/api/studies", tags=["studies"], responses=AUTH_RESPONSES)


def _name_taken(db: SessionDep, name: str, but: int | None = None) -> bool:
    found = db.scalars(select(Study.id).where(Study.name == name)).first()
    return found is not None and found != but


@router.get("", response_model=list[StudyOut])
def list_studies(user: CurrentUser, db: SessionDep) -> list[Study]:
    """Every study, oldest first."""
    return list(db.scalars(select(Study).order_by(Study.id)))


@router.post("", response_model=StudyOut, status_code=201,
             responses={**BODY, **CONFLICT})
def create_study(body: StudyIn, user: CurrentUser, db: SessionDep) -> Study:
    """Create a study; 409 if the name is taken."""
    if _name_taken(db, body.name):
        conflict("name", f"a study named {body.name!r} exists")
    study = Study(name=body.name, description=body.description, created_by=user.id)
    db.add(study)
    db.flush()
    audit.record(db, user, "create", "study", study.id, body.model_dump(mode="json"))
    commit_or_conflict(db, "name", f"a study named {body.name!r} exists")
    return study


@router.get("/{study_id}", response_model=StudyOut, responses={**NOT_FOUND, **INVALID})
def get_study(study_id: StudyId, user: CurrentUser, db: SessionDep) -> Study:
    """One study."""
    return one_or_404(db, Study, study_id, "study")


@router.patch("/{study_id}", response_model=StudyOut,
              responses={**NOT_FOUND, **BODY, **CONFLICT})
def update_study(study_id: StudyId, body: StudyUpdate, user: CurrentUser, db: SessionDep
                 ) -> Study:
    """Rename a study or change its description."""
    study = one_or_404(db, Study, study_id, "study")
    changes = body.model_dump(mode="json", exclude_unset=True, exclude_none=True)
    if "name" in changes and _name_taken(db, changes["name"], but=study.id):
        conflict("name", f"a study named {changes['name']!r} exists")
    for field, value in changes.items():
        setattr(study, field, value)
    audit.record(db, user, "update", "study", study.id, changes)
    commit_or_conflict(db, "name", "a study with this name exists")
    return study
