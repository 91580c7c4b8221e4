"""The server's cache of study evaluations: the tables, figures and JSON of one study are
often fetched together, and evaluating reads every tick of the study, so an evaluation is
reused while nothing it depends on (`fingerprint`) has changed."""

from __future__ import annotations

from typing import Any

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis.results import StudyResults, counted, study_results
from backend.db.evidence_tables import Trial, TrialSegment
from backend.db.models import (
    ConditionLabel,
    Participant,
    Preference,
    QuestionnaireResponse,
    StudySession,
)


class ResultsCache:
    """The last few study evaluations, keyed by everything they read (`fingerprint`).

    The tables, figures and JSON of one study are often fetched together and evaluating
    reads every tick; an entry is reused only while nothing it depends on changed."""

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self._entries: dict[tuple[Any, ...], StudyResults] = {}

    def get(self, engine: Engine, db: Session, study_id: int,
            site: str | None) -> StudyResults:
        """The study's results for a caller limited to `site` (None: every site)."""
        key = fingerprint(db, study_id, site)
        hit = self._entries.get(key)
        if hit is None:
            hit = study_results(engine, db, study_id, site)
            if len(self._entries) >= self.size:
                self._entries.pop(next(iter(self._entries)))
            self._entries[key] = hit
        return hit


def fingerprint(db: Session, study_id: int, site: str | None = None) -> tuple[Any, ...]:
    """What the study's results depend on, cheaply: its trials' states and runs and its
    questionnaire answers. Equal fingerprints give equal results, so a caller may reuse
    an evaluation (reading every tick of a study takes seconds)."""
    trials = tuple(db.execute(
        select(Trial.id, Trial.status, Trial.run_id, Trial.ended_at)
        .join(StudySession, Trial.session_id == StudySession.id)
        .join(Participant, StudySession.participant_id == Participant.id)
        .where(counted(study_id, site)).order_by(Trial.id)).all())
    people = select(Participant.id).where(counted(study_id, site))
    codes = tuple(db.execute(select(Participant.id, Participant.code).where(
        counted(study_id, site)).order_by(Participant.id)).all())  # tables name them
    answers = tuple(db.scalars(select(QuestionnaireResponse.id).where(
        QuestionnaireResponse.participant_id.in_(people)).order_by(
        QuestionnaireResponse.id)))
    prefs = tuple(db.scalars(select(Preference.id).where(
        Preference.participant_id.in_(people)).order_by(Preference.id)))
    segs = tuple(db.execute(select(TrialSegment.id, TrialSegment.updated_at)
                            .join(Trial, TrialSegment.trial_id == Trial.id)
                            .join(StudySession, Trial.session_id == StudySession.id)
                            .where(StudySession.participant_id.in_(people))
                            .order_by(TrialSegment.id)).all())
    labels = tuple(db.execute(select(ConditionLabel.participant_id, ConditionLabel.label,
                                     ConditionLabel.controller).where(
        ConditionLabel.participant_id.in_(people)).order_by(ConditionLabel.id)).all())
    return (study_id, site, trials, codes, answers, prefs, labels, segs)
