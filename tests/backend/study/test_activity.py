"""Closing what ran when its worker or server stopped: interrupted, unless its timed run
had already reached its time limit (then its data is whole and it closes as the
experimenter's stop would have)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.db import migrate
from backend.db.engine import make_engine
from backend.db.evidence_tables import Recording, Trial
from backend.live.recorder import TickRecorder
from backend.study import activity
from backend.worker.messages import RunStarted, TickBatch
from controller.tick_record import TickRecord
from tests.session_rows import evaluation_session


def _runs(rec: TickRecorder) -> tuple[int, int]:
    """A timed run of 5 ticks that reached its limit, then the open run after it."""
    timed = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
    rec.add(TickBatch.from_records(1, (TickRecord(seq=k, t=k / 100) for k in range(5))))
    after = rec.run_started(RunStarted(2, "none", {}, "sim", 1, None, 5), "sim")
    rec.add(TickBatch.from_records(2, (TickRecord(seq=k, t=k / 100) for k in range(5, 8))))
    rec.flush()
    return timed, after


def test_only_what_was_cut_short_is_interrupted(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    with Session(engine) as db:
        sid = evaluation_session(db, "closing", "P01").id
        db.commit()

    def running(trial_run: int, recording_run: int) -> tuple[int, int]:
        with Session(engine) as db:
            trial = Trial(session_id=sid, controller="umc", task="squat-sequence",
                          planned_order=0, status="running", run_id=trial_run)
            recording = Recording(session_id=sid, run_id=recording_run)
            db.add_all([trial, recording])
            db.commit()
            return trial.id, recording.id

    def closed(trial_id: int, recording_id: int) -> tuple[tuple[str, str, int | None], str]:
        with Session(engine) as db:
            t = db.scalars(select(Trial).where(Trial.id == trial_id)).one()
            r = db.scalars(select(Recording).where(Recording.id == recording_id)).one()
            return (t.status, t.end_reason, t.tick_count), r.status

    # The trial's timed run was over; the recording's run was still going.
    timed, after = _runs(rec)
    tid, rid = running(timed, after)
    said = activity.interrupt_running(engine, "the worker stopped: killed by SIGKILL")
    assert said == [f"trial {tid} (completed: its time was up)", f"recording {rid}"]
    trial, recording = closed(tid, rid)
    assert trial == ("completed", "its timed run had ended before it was stopped "
                     "(the worker stopped: killed by SIGKILL)", 5)
    assert recording == "interrupted"

    # The other way round; and at the next server start (`recover`) alike.
    timed, after = _runs(rec)
    tid, rid = running(after, timed)
    said = activity.recover(engine)
    assert said[:2] == [f"trial {tid}", f"recording {rid} (stopped: its time was up)"]
    trial, recording = closed(tid, rid)
    assert trial[0] == "interrupted" and trial[2] == 3
    assert recording == "stopped"
    engine.dispose()
