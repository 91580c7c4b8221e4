"""A participant's withdrawal: erase everything held about them, or keep it excluded.

Which one is the study's protocol's decision (`Study.withdrawal_policy`). Erasure
deletes the participant row (sessions, blinding key, links, answers, preferences,
recordings, trials and their segments follow by ON DELETE CASCADE), the ticks their
trials and recordings stored, and the details of earlier audit entries about them; the
audit entry it writes names the participant id and nothing else, so the log proves the
erasure without keeping what was erased. Their EMG recording files (beside the database,
not in it) are deleted after the commit; a file that cannot be deleted is logged and
left an orphan that `exostudy doctor` lists (the rows are gone either way).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Literal

from sqlalchemy import delete, select, update
from sqlalchemy.orm import Session

from backend.db import audit
from backend.db.emg import EmgRecording
from backend.db.evidence_tables import Recording, Trial
from backend.db.models import AuditEntry, Participant, Run, Study, StudySession, User, ticks_table
from backend.emg import recovery, store

Outcome = Literal["erased", "excluded"]


def _erase_ticks(db: Session, participant_id: int) -> None:
    sessions = select(StudySession.id).where(StudySession.participant_id == participant_id)
    trial_runs = set(db.scalars(select(Trial.run_id).where(
        Trial.session_id.in_(sessions), Trial.run_id.is_not(None))))
    if trial_runs:
        # A trial has a run of its own: the run and its ticks go.
        db.execute(delete(ticks_table).where(ticks_table.c.run_id.in_(trial_runs)))
        db.execute(delete(Run).where(Run.id.in_(trial_runs)))
    for rec in db.scalars(select(Recording).where(Recording.session_id.in_(sessions))):
        # A recording is a stretch of a worker run: only its ticks go.
        if rec.run_id is not None and rec.first_tick_id is not None:
            last = rec.last_tick_id if rec.last_tick_id is not None else rec.first_tick_id
            db.execute(delete(ticks_table).where(
                ticks_table.c.run_id == rec.run_id,
                ticks_table.c.id.between(rec.first_tick_id, last)))


def withdraw(db: Session, p: Participant, actor: User, emg_folder: Path | None = None
             ) -> Outcome:
    """Apply the study's withdrawal policy to `p` and commit; an erasure then deletes
    the EMG files in `emg_folder` (default: the database's EMG folder)."""
    emg_ids = list(db.scalars(select(EmgRecording.id).join(
        StudySession, StudySession.id == EmgRecording.session_id)
        .where(StudySession.participant_id == p.id)))
    outcome = _apply(db, p, actor)
    db.commit()
    if outcome == "erased" and emg_ids:
        folder = emg_folder or store.engine_emg_folder(db.get_bind().engine)
        recovery.delete_files(folder, emg_ids)
    return outcome


def _apply(db: Session, p: Participant, actor: User) -> Outcome:
    """The policy's changes and the audit entry, not committed."""
    study = db.get(Study, p.study_id)
    policy = study.withdrawal_policy if study is not None else "erase"
    pid, study_id = p.id, p.study_id
    if policy == "exclude":
        p.withdrawn_at = datetime.now(UTC)
        audit.record(db, actor, "withdraw", "participant", pid,
                     {"study_id": study_id, "outcome": "excluded"})
        return "excluded"
    _erase_ticks(db, pid)
    db.delete(p)
    db.flush()
    # Earlier entries about the participant held their data (age, mass, notes): keep
    # that something happened, not what.
    db.execute(update(AuditEntry).where(AuditEntry.entity == "participant",
                                        AuditEntry.entity_id == str(pid))
               .values(details={"erased": True}))
    audit.record(db, actor, "withdraw", "participant", pid,
                 {"study_id": study_id, "outcome": "erased"})
    return "erased"
