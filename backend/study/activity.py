"""What the worker is doing for the study: at most one recording or trial at a time.

Starting one switches the worker's controller, which starts a new run; the recording or
trial keeps that run's id, so its ticks are exactly the run's ticks.

The rule "at most one" holds three times over: the routes that start, stop or switch
hold the runtime's activity lock (no check-then-act between two requests), the check
below answers 409, and partial unique indexes in the database refuse a second running
row whatever happens (0005_safety).

Ending is done here too, the same way for every cause: a trial stopped by the
experimenter, or interrupted because its worker or server died. The status changes
only if it is still `running` (one conditional UPDATE), so two closers never both win.
"""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy import Engine, func, select, update
from sqlalchemy.orm import Session

from backend.analysis import lock_events, tick_queries
from backend.core.errors import ConflictError
from backend.db.evidence_tables import LockEvent, Recording, Trial
from backend.db.models import Run, ticks_table
from backend.live import trial_quality
from backend.worker.messages import TIME_LIMIT_REACHED


def running(db: Session) -> str | None:
    """What runs now ("trial 3", "recording 5"), or None."""
    rec = db.scalar(select(Recording.id).where(Recording.status == "recording"))
    if rec is not None:
        return f"recording {rec}"
    trial = db.scalar(select(Trial.id).where(Trial.status == "running"))
    if trial is not None:
        return f"trial {trial}"
    return None


def ensure_idle(db: Session) -> None:
    """409 if a recording or a trial is already running."""
    rec = db.scalar(select(Recording.id).where(Recording.status == "recording"))
    if rec is not None:
        raise ConflictError("recording", f"recording {rec} is still running; stop it first")
    trial = db.scalar(select(Trial.id).where(Trial.status == "running"))
    if trial is not None:
        raise ConflictError("trial", f"trial {trial} is still running; stop it first")


def close_trial(db: Session, engine: Engine, trial_id: int, status: str, reason: str) -> bool:
    """End a running trial as `status` (completed, aborted, interrupted) with `reason`:
    its tick count, quality flags and lock events from its stored ticks. Returns False
    (and changes nothing) if the trial was no longer running. Commits."""
    now = datetime.now(UTC)
    won = db.execute(update(Trial).where(Trial.id == trial_id, Trial.status == "running")
                     .values(status=status, ended_at=now, end_reason=reason))
    if won.rowcount != 1:  # type: ignore[attr-defined]
        db.rollback()
        return False
    trial = db.get(Trial, trial_id)
    assert trial is not None
    db.refresh(trial)
    if trial.run_id is not None:
        cols = tick_queries.columns(engine, trial.run_id, fields=lock_events.TICK_FIELDS)
        trial.tick_count = int(cols["t"].size)
        trial.quality_flags = trial_quality.assess(cols["t"])
        if cols["t"].size:
            for ev in lock_events.derive(cols):
                db.add(LockEvent(trial_id=trial.id, t=ev.t, side=ev.side, kind=ev.kind,
                                 torque_peak=ev.torque_peak))
    else:
        trial.tick_count = 0
    db.commit()
    return True


def close_recording(db: Session, engine: Engine, recording_id: int, status: str) -> bool:
    """End a running recording as `status` (stopped, interrupted) with its tick range;
    False if it was no longer recording. Commits."""
    won = db.execute(update(Recording).where(Recording.id == recording_id,
                                             Recording.status == "recording")
                     .values(status=status, ended_at=datetime.now(UTC)))
    if won.rowcount != 1:  # type: ignore[attr-defined]
        db.rollback()
        return False
    rec = db.get(Recording, recording_id)
    assert rec is not None
    db.refresh(rec)
    if rec.run_id is not None:
        rec.first_tick_id, rec.last_tick_id = tick_queries.tick_id_range(engine, rec.run_id)
    db.commit()
    return True


def _timed_out(db: Session, run_id: int | None) -> bool:
    """Whether the run ended by reaching its time limit: the trial or recording it was
    started for holds every sample it asked for, and only waited to be closed."""
    return run_id is not None and db.scalar(
        select(Run.end_reason).where(Run.id == run_id)) == TIME_LIMIT_REACHED


def interrupt_running(engine: Engine, reason: str) -> list[str]:
    """Close every running trial and recording as `interrupted` (their worker or server
    died); returns what was closed, e.g. ["trial 3"]. A timed one whose run had already
    reached its time limit is whole: it closes as the experimenter's stop would have
    (completed, stopped), its reason saying when."""
    closed: list[str] = []
    with Session(engine) as db:
        for tid, run_id in list(db.execute(select(Trial.id, Trial.run_id)
                                           .where(Trial.status == "running"))):
            if _timed_out(db, run_id):
                if close_trial(db, engine, tid, "completed",
                               f"its timed run had ended before it was stopped ({reason})"):
                    closed.append(f"trial {tid} (completed: its time was up)")
            elif close_trial(db, engine, tid, "interrupted", reason):
                closed.append(f"trial {tid}")
        for rid, run_id in list(db.execute(select(Recording.id, Recording.run_id)
                                           .where(Recording.status == "recording"))):
            whole = _timed_out(db, run_id)
            if close_recording(db, engine, rid, "stopped" if whole else "interrupted"):
                closed.append(f"recording {rid}" + (" (stopped: its time was up)"
                                                    if whole else ""))
    return closed


def close_open_runs(engine: Engine, reason: str) -> int:
    """Close runs left open by a server that died: their stored tick counts and the
    reason. Returns how many. Call before a new worker starts."""
    now = datetime.now(UTC)
    with Session(engine) as db:
        ids = list(db.scalars(select(Run.id).where(Run.ended_at.is_(None))))
        for run_id in ids:
            n = db.scalar(select(func.count()).select_from(ticks_table)
                          .where(ticks_table.c.run_id == run_id)) or 0
            db.execute(update(Run).where(Run.id == run_id)
                       .values(ended_at=now, end_reason=reason[:200], tick_count=int(n)))
        db.commit()
    return len(ids)


def recover(engine: Engine) -> list[str]:
    """At server start: what a dead server left running is closed as interrupted, and
    its runs with their real tick counts. Returns what was closed."""
    reason = "the server stopped while it ran (closed at the next server start)"
    closed = interrupt_running(engine, reason)
    n = close_open_runs(engine, reason)
    if n:
        closed.append(f"{n} run(s)")
    return closed
