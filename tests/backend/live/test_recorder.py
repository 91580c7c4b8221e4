"""Batched tick writing: runs, order, failures that keep the data, and SQLite's rows
stored as the codec's."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st
from sqlalchemy import select

from backend.db import migrate
from backend.db.engine import make_engine
from backend.db.models import TICK_DATA_COLUMNS, Run, ticks_table
from backend.live.recorder import TickRecorder, sqlite_rows
from backend.worker.messages import TIME_LIMIT_REACHED, RunStarted, TickBatch
from controller.tick_codec import FIELD_KINDS, FIELD_NAMES, db_rows, pack
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


def test_a_run_the_worker_ended_at_its_time_limit_is_whole_only_if_all_is_stored(
        db_url: str) -> None:
    """The worker says a run ended at its time limit after N samples; the stored run
    says so (what closes a timed trial whole when its worker stops before the
    experimenter) only when exactly N of its ticks are stored: not when the backlog
    dropped some, nor while a failed write still holds them."""
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine, backlog_limit=40)
    whole = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
    rec.add(_batch(1, range(4)))
    dropped = rec.run_started(RunStarted(2, "umc", {}, "sim", 1, None, 4), "sim")
    rec.add(_batch(2, range(100)))  # 60 of them over the backlog limit: dropped
    unwritten = rec.run_started(RunStarted(3, "umc", {}, "sim", 1, None, 100), "sim")
    rec.add(_batch(3, range(30)))
    real = rec._insert_sql
    rec._insert_sql = lambda run_id: "INSERT INTO no_such_table VALUES (1)"  # type: ignore[method-assign]
    rec.run_started(RunStarted(4, "none", {}, "sim", 1, None, 30), "sim")
    rec._insert_sql = real  # type: ignore[method-assign]
    assert rec.failures == 1 and rec.backlog == 30  # kept for the next attempt
    with engine.connect() as conn:
        reasons = {r.id: (r.end_reason, r.tick_count) for r in conn.execute(select(Run))}
    assert reasons[whole] == (TIME_LIMIT_REACHED, 4)
    assert reasons[dropped] == ("controller changed", 40)
    assert reasons[unwritten] == ("controller changed", 0)
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


_VALUES: dict[str, st.SearchStrategy[Any]] = {
    "float": st.floats(width=64),  # NaN and infinities too
    "int": st.integers(-(2**63), 2**63 - 1),
    "bool": st.booleans(),
    "str": st.sampled_from(["", "stand", "squat", "stoop_left", "walk"]),
}
_RECORDS = st.lists(st.builds(TickRecord, **{n: _VALUES[FIELD_KINDS[n]] for n in FIELD_NAMES}),
                    min_size=1, max_size=6)


def test_sqlite_stores_the_recorders_rows_as_the_codecs_rows(tmp_path: Path) -> None:
    """The recorder binds booleans as 0/1 (cheaper for SQLite's driver): every stored
    value and its SQLite type equal those of the codec's rows (`db_rows`) inserted as
    they are."""
    db_url = f"sqlite:///{tmp_path / 'exostudy.db'}"
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    cols = ", ".join(f'"{c}"' for c in TICK_DATA_COLUMNS)
    stored = cols + ", " + ", ".join(f'typeof("{c}")' for c in TICK_DATA_COLUMNS)
    marks = ", ".join("?" for _ in TICK_DATA_COLUMNS)

    def read(conn: Any, run_id: int) -> list[tuple[Any, ...]]:
        return conn.exec_driver_sql(f"SELECT {stored} FROM ticks WHERE run_id = {run_id} "
                                    "ORDER BY id").all()

    @settings(max_examples=30, deadline=None)
    @given(_RECORDS)
    def check(records: list[TickRecord]) -> None:
        block = pack(records)
        for mine, codec in zip(sqlite_rows(block), db_rows(block, nan_as_null=False),
                               strict=True):  # True == 1; NaN where NaN
            assert all(a == b or (a != a and b != b) for a, b in zip(mine, codec, strict=True))
        token = len(rec._runs) + 1
        run_id = rec.run_started(RunStarted(token, "none", {}, "sim", 1), "sim")
        rec.add(TickBatch(token, block))
        assert rec.flush() == len(records)
        with engine.begin() as conn:
            ref = run_id + 100_000  # the codec's rows as they are, as a run of their own
            conn.exec_driver_sql(f"INSERT INTO runs (id, started_at, device_kind, controller, "
                                 f"config_json, tick_count) VALUES ({ref}, '2026-01-01', "
                                 "'sim', 'none', '{}', 0)")
            conn.exec_driver_sql(f"INSERT INTO ticks (run_id, {cols}) VALUES ({ref}, {marks})",
                                 db_rows(block, nan_as_null=False))
            assert read(conn, run_id) == read(conn, ref)

    check()
    engine.dispose()
