"""Studies, their members and their consent documents: the queries and writes behind
`/api/studies` (the routes parse, authorise and call these)."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db import audit
from backend.db.models import ConsentDocument, Study, StudyMember, User
from backend.schemas.studies import ConsentIn, MemberIn, MemberOut, StudyIn, StudyUpdate
from backend.study import access
from backend.study.writes import commit_or_conflict


def get(db: Session, study_id: int) -> Study:
    """The study; `NotFoundError` if there is none."""
    study = db.get(Study, study_id)
    if study is None:
        raise NotFoundError("study", study_id)
    return study


def _name_taken(db: Session, name: str, but: int | None = None) -> bool:
    found = db.scalars(select(Study.id).where(Study.name == name)).first()
    return found is not None and found != but


def visible(db: Session, user: User) -> list[Study]:
    """The studies `user` is a member of (an admin: every study), oldest first."""
    q = select(Study).order_by(Study.id)
    ids = access.visible_study_ids(db, user)
    if ids is not None:
        q = q.where(Study.id.in_(ids))
    return list(db.scalars(q))


def create(db: Session, user: User, body: StudyIn) -> Study:
    """A new study owned by its creator; a conflict if the name is taken."""
    taken = f"a study named {body.name!r} exists"
    if _name_taken(db, body.name):
        raise ConflictError("name", taken)
    study = Study(name=body.name, description=body.description, created_by=user.id,
                  withdrawal_policy=body.withdrawal_policy,
                  dataset_info=body.dataset_info.model_dump(mode="json"))
    db.add(study)
    db.flush()
    db.add(StudyMember(study_id=study.id, user_id=user.id, role="owner"))
    audit.record(db, user, "create", "study", study.id, body.model_dump(mode="json"))
    commit_or_conflict(db, "name", taken)
    return study


def update(db: Session, user: User, study_id: int, body: StudyUpdate) -> Study:
    """Apply the fields given; a conflict if the new name is another study's."""
    study = get(db, study_id)
    changes = body.model_dump(mode="json", exclude_unset=True, exclude_none=True)
    if "name" in changes and _name_taken(db, changes["name"], but=study.id):
        raise ConflictError("name", f"a study named {changes['name']!r} exists")
    for field, value in changes.items():
        setattr(study, field, value)
    audit.record(db, user, "update", "study", study.id, changes)
    commit_or_conflict(db, "name", "a study with this name exists")
    return study


def members(db: Session, study_id: int) -> list[MemberOut]:
    """Who has which role in the study (and which site), by username."""
    rows = db.execute(select(StudyMember, User.username)
                      .join(User, User.id == StudyMember.user_id)
                      .where(StudyMember.study_id == study_id).order_by(User.username))
    return [MemberOut(user_id=m.user_id, username=name, role=m.role, site=m.site)
            for m, name in rows]


def _membership(db: Session, study_id: int, username: str
                ) -> tuple[User | None, StudyMember | None]:
    target = db.scalars(select(User).where(User.username == username)).first()
    row = None if target is None else db.scalars(select(StudyMember).where(
        StudyMember.study_id == study_id, StudyMember.user_id == target.id)).first()
    return target, row


def set_member(db: Session, user: User, study_id: int, body: MemberIn) -> list[MemberOut]:
    """Give an account a role in the study, or change its role or site."""
    target, row = _membership(db, study_id, body.username)
    if target is None:
        raise InvalidError.at(["body", "username"], f"no account named {body.username!r}")
    if row is None:
        db.add(StudyMember(study_id=study_id, user_id=target.id, role=body.role,
                           site=body.site))
    else:
        row.role, row.site = body.role, body.site
    audit.record(db, user, "set_member", "study", study_id, body.model_dump())
    commit_or_conflict(db, "username", "is already a member")
    return members(db, study_id)


def remove_member(db: Session, user: User, study_id: int, username: str) -> None:
    """Take an account's role in the study away; `NotFoundError` if it has none."""
    _target, row = _membership(db, study_id, username)
    if row is None:
        raise NotFoundError("member", username)
    db.delete(row)
    audit.record(db, user, "remove_member", "study", study_id, {"username": username})
    db.commit()


def consent_documents(db: Session, study_id: int) -> list[ConsentDocument]:
    """The study's consent document versions, oldest first."""
    return list(db.scalars(select(ConsentDocument).where(ConsentDocument.study_id == study_id)
                           .order_by(ConsentDocument.id)))


def add_consent(db: Session, user: User, study_id: int, body: ConsentIn) -> ConsentDocument:
    """A new consent document version (versions are never edited)."""
    if db.scalars(select(ConsentDocument.id).where(
            ConsentDocument.study_id == study_id,
            ConsentDocument.version == body.version)).first() is not None:
        raise ConflictError("version", f"version {body.version!r} exists; add a new version "
                            "instead")
    doc = ConsentDocument(study_id=study_id, version=body.version, text=body.text)
    db.add(doc)
    db.flush()
    audit.record(db, user, "create", "consent", doc.id, {"study_id": study_id,
                                                         "version": body.version})
    commit_or_conflict(db, "version", f"version {body.version!r} exists")
    return doc


def record_export(db: Session, user: User, study_id: int, action: str,
                  details: dict[str, Any]) -> None:
    """Audit an export download (`action`, e.g. export_deidentified; `details`: its
    format and size)."""
    audit.record(db, user, action, "study", study_id, details)
    db.commit()
