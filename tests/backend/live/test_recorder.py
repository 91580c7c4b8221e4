"""Batched tick writing: runs, order, failures that keep the data."""

from __future__ import annotations

from sqlalchemy import select

from backend.db import migrate
from backend.db.engine import make_engine
from backend.db.models import Run, ticks_table
from backend.live.recorder import TickRecorder
from backend.worker.messages import RunStarted, TickBatch
from controller.tick_record import TickRecord


def _batch(token: int, seqs: range) -> TickBatch:
    return TickBatch.from_records(
        token, tuple(TickRecord(seq=s, t=s / 100, q_left=s * 0.01) for s in seqs))


def test_ticks_land_in_their_run_with_every_field(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    run_id = rec.run_started(RunStarted(1, "none", {}, "sim", 123), "sim")
    rec.add(_batch(1, range(0, 150)))
    assert rec.flush() == 150
    rec.worker_exited("killed by SIGKILL")
    with engine.connect() as conn:
        rows = conn.execute(select(ticks_table).order_by(ticks_table.c.id)).mappings().all()
        run = conn.execute(select(Run)).one()
    assert [r["seq"] for r in rows] == list(range(150))
    assert rows[10]["q_left"] == 0.1
    assert rows[10]["omega_left"] is None  # NaN, "not computed", is stored as NULL
    assert {r["run_id"] for r in rows} == {run_id}
    assert run.end_reason == "killed by SIGKILL"
    assert run.tick_count == 150
    engine.dispose()


def test_a_controller_change_closes_the_old_run(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    first = rec.run_started(RunStarted(1, "none", {}, "sim", 1), "sim")
    rec.add(_batch(1, range(5)))
    second = rec.run_started(RunStarted(2, "pec", {"threshold": 1.0}, "sim", 1), "sim")
    rec.add(_batch(2, range(5, 8)))
    rec.flush()
    with engine.connect() as conn:
        runs = {r.id: r for r in conn.execute(select(Run)).all()}
        per_run = dict(
            conn.execute(
                select(ticks_table.c.run_id, ticks_table.c.seq).order_by(ticks_table.c.id.desc())
            ).all()
        )
    assert runs[first].end_reason == "controller changed"
    assert runs[second].controller == "pec"
    assert runs[second].ended_at is None
    assert set(per_run) == {first, second}
    engine.dispose()


def test_a_failed_write_keeps_the_ticks_for_the_next_flush(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    rec.run_started(RunStarted(1, "none", {}, "sim", 1), "sim")
    rec.add(_batch(1, range(10)))
    with engine.begin() as conn:
        conn.exec_driver_sql("ALTER TABLE ticks RENAME TO ticks_away")
    assert rec.flush() == 0
    assert rec.failures == 1 and "ticks" in rec.last_error
    with engine.begin() as conn:
        conn.exec_driver_sql("ALTER TABLE ticks_away RENAME TO ticks")
    assert rec.flush() == 10
    engine.dispose()
