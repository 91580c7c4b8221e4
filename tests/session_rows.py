"""A study, a participant and an evaluation session written straight into a migrated
database: what tests of the layers below the API start from."""

from __future__ import annotations

from typing import Any

from sqlalchemy.orm import Session

from backend.db.models import Participant, Study, StudySession


def evaluation_session(db: Session, study: str = "S", code: str = "P1",
                       **participant: Any) -> StudySession:
    """The new session (flushed, not committed), of a new participant `code` of a new
    study named `study`."""
    s = Study(name=study)
    db.add(s)
    db.flush()
    p = Participant(study_id=s.id, code=code, **participant)
    db.add(p)
    db.flush()
    sess = StudySession(participant_id=p.id, kind="evaluation", precompression_pct=25)
    db.add(sess)
    db.flush()
    return sess
