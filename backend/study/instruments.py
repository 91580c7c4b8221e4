"""The questionnaire instruments a study may use: the built-ins and its own, never
another study's; and importing a study's own definition (checked for shape by
`backend.questionnaires` before it gets here)."""

from __future__ import annotations

from typing import Any

from sqlalchemy import ColumnElement, or_, select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError
from backend.db import audit
from backend.db.models import QuestionnaireInstrument, User
from backend.study.writes import commit_or_conflict


def _visible(study_id: int | None) -> ColumnElement[bool]:
    """The instruments a study may use: the built-ins and its own, never another
    study's (None: the built-ins only)."""
    built_in = QuestionnaireInstrument.built_in.is_(True)
    if study_id is None:
        return built_in
    return or_(built_in, QuestionnaireInstrument.study_id == study_id)


def of_study(db: Session, study_id: int | None) -> list[QuestionnaireInstrument]:
    """Every instrument a study may use, by key and age (None: the built-ins)."""
    return list(db.scalars(select(QuestionnaireInstrument).where(_visible(study_id))
                           .order_by(QuestionnaireInstrument.key, QuestionnaireInstrument.id)))


def find(db: Session, study_id: int | None, key: str, version: str
         ) -> QuestionnaireInstrument | None:
    """One version of an instrument the study may use (a built-in before the study's)."""
    return db.scalars(select(QuestionnaireInstrument).where(
        _visible(study_id), QuestionnaireInstrument.key == key,
        QuestionnaireInstrument.version == version)
        .order_by(QuestionnaireInstrument.built_in.desc())).first()


def resolve_for_link(db: Session, study_id: int, key: str, version: str | None
                     ) -> QuestionnaireInstrument | str:
    """The instrument a link's form asks for, or what is wrong.

    Without a version the key must have exactly one version the study may use: a link
    is never given whichever version someone imported last.
    """
    if version is not None:
        row = find(db, study_id, key, version)
        return row if row is not None else f"no instrument {key} {version} in this study"
    rows = [r for r in of_study(db, study_id) if r.key == key]
    if not rows:
        return f"no instrument {key} in this study"
    if len(rows) > 1:
        return (f"instrument {key} has versions {[r.version for r in rows]} in this study; "
                "name one in instrument_version")
    return rows[0]


def add_to_study(db: Session, user: User, study_id: int, key: str, version: str, title: str,
                 definition: dict[str, Any]) -> QuestionnaireInstrument:
    """Store a study's own instrument (its definition already validated); a key and
    version the study has is a conflict (import a new version). Audited, committed."""
    if db.scalars(select(QuestionnaireInstrument.id).where(
            QuestionnaireInstrument.study_id == study_id,
            QuestionnaireInstrument.key == key,
            QuestionnaireInstrument.version == version)).first() is not None:
        raise ConflictError("version", f"instrument {key!r} version {version!r} "
                            "exists in this study; import it under a new version")
    row = QuestionnaireInstrument(key=key, version=version, title=title, definition=definition,
                                  built_in=False, study_id=study_id, created_by=user.id)
    db.add(row)
    db.flush()
    audit.record(db, user, "import", "instrument", row.id,
                 {"study_id": study_id, "key": key, "version": version})
    commit_or_conflict(db, "version", "this key and version exist in this study")
    return row
