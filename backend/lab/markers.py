"""Storing event markers: which trial a marker belongs to, and the study's marker labels.

A marker belongs to the trial of its session whose run produced the tick it is placed
at; a marker between trials belongs to the session only.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker, StudyMarkerLabels
from backend.db.models import ConditionLabel, StudySession
from backend.lab.lsl_outlets import TickTime
from backend.schemas.lab import DEFAULT_MARKER_LABELS


def trial_of(db: Session, session_id: int, run_id: int | None) -> int | None:
    """The session's trial that ran as `run_id`, if any."""
    if run_id is None:
        return None
    return db.scalar(select(Trial.id).where(Trial.session_id == session_id,
                                            Trial.run_id == run_id))


def check_console_tick(db: Session, session_id: int, tick: TickTime | None) -> None:
    """Refuse (409) a console marker whose newest tick is not of the session's running
    trial: a timed trial's run ends at its duration while the trial stays running
    until stopped, and the newest tick is then another run's. Stored, the marker
    would belong to neither the trial nor its time axis."""
    trial = db.scalar(select(Trial).where(Trial.session_id == session_id,
                                          Trial.status == "running"))
    if trial is None or trial.run_id is None or tick is None or tick.run_id == trial.run_id:
        return
    raise ConflictError("trial", f"trial {trial.id} is still running but its ticks have "
                        "ended (a timed trial's duration is over): stop it with "
                        f"POST /api/trials/{trial.id}/stop; a marker now would fall "
                        "outside it")


def store(db: Session, session_id: int, label: str, note: str, source: str,
          tick: TickTime | None, lsl_time: float | None = None, stream_id: int | None = None,
          user_id: int | None = None, flush: bool = True) -> Marker:
    """Add a marker at `tick` (None: no tick has arrived yet; the marker keeps its LSL
    time only). The caller commits; without `flush` nothing is written before that."""
    run_id = tick.run_id if tick is not None else None
    marker = Marker(session_id=session_id, trial_id=trial_of(db, session_id, run_id),
                    run_id=run_id, t=tick.t if tick is not None else None,
                    lsl_time=lsl_time if lsl_time is not None
                    else (tick.lsl_time if tick is not None else None),
                    label=label[:100], note=note, source=source, stream_id=stream_id,
                    created_by=user_id)
    db.add(marker)
    if flush:
        db.flush()
    return marker


def labels(db: Session, study_id: int) -> list[str]:
    """The study's marker labels (the defaults until the study sets its own)."""
    row = db.get(StudyMarkerLabels, study_id)
    return list(row.labels) if row is not None else list(DEFAULT_MARKER_LABELS)


def trial_fields(db: Session, trial: Trial) -> dict[str, Any]:
    """What a trial's LSL markers say about it: id, task, controller and the blinded
    label the participant knows it by."""
    participant_id = db.scalar(select(StudySession.participant_id)
                               .where(StudySession.id == trial.session_id))
    label = db.scalar(select(ConditionLabel.label).where(
        ConditionLabel.participant_id == participant_id,
        ConditionLabel.controller == (trial.condition or trial.controller)))
    return {"trial_id": trial.id, "task": trial.task, "controller": trial.controller,
            "blinded_label": label}

