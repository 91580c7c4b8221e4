"""Migration 0010 on a database with a study in it: nothing is lost (SQLite rebuilds a
table to alter it; with foreign keys on, dropping the old `studies` table cascaded and
deleted every participant, session and trial), and every existing participant and study
gets a date shift of its own, kept from then on."""

from __future__ import annotations

import pytest
from sqlalchemy import text

from backend.db import migrate
from backend.db.engine import make_engine

NOW = "2026-03-02 10:00:00"


def _fill(db_url: str) -> None:
    engine = make_engine(db_url)
    with engine.begin() as conn:
        conn.execute(text(
            "INSERT INTO studies (id, name, description, created_at, withdrawal_policy) "
            "VALUES (1, 'kept', '', :now, 'erase')"), {"now": NOW})
        for pid in (1, 2):
            conn.execute(text(
                "INSERT INTO participants (id, study_id, code, notes, created_at) "
                "VALUES (:id, 1, :code, '', :now)"), {"id": pid, "code": f"P0{pid}", "now": NOW})
            conn.execute(text(
                "INSERT INTO study_sessions (id, participant_id, kind, precompression_pct, "
                "started_at, notes, created_at) VALUES (:id, :id, 'evaluation', 25, :now, "
                "'', :now)"), {"id": pid, "now": NOW})
            conn.execute(text(
                "INSERT INTO trials (id, session_id, controller, task, planned_order, status, "
                "end_reason) VALUES (:id, :id, 'pec', 'walking', 0, 'completed', '')"),
                {"id": pid})
    engine.dispose()


def _count(db_url: str, table: str) -> int:
    engine = make_engine(db_url)
    with engine.connect() as conn:
        n = int(conn.execute(text(f"SELECT COUNT(*) FROM {table}")).scalar_one())
    engine.dispose()
    return n


def test_0010_keeps_every_row_and_draws_a_shift_per_participant(db_url: str) -> None:
    if not db_url.startswith("sqlite"):
        pytest.skip("table rebuilds are SQLite's")
    migrate.upgrade(db_url, "0009")
    _fill(db_url)
    migrate.upgrade(db_url, "0010")
    for table, n in (("studies", 1), ("participants", 2), ("study_sessions", 2),
                     ("trials", 2)):
        assert _count(db_url, table) == n, table
    engine = make_engine(db_url)
    with engine.connect() as conn:
        shifts = [r[0] for r in conn.execute(text("SELECT date_shift_days FROM participants"))]
        study = conn.execute(text("SELECT date_shift_days, dataset_info FROM studies")).one()
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
    engine.dispose()
    assert all(1 <= s <= 364 for s in shifts) and len(shifts) == 2
    assert 1 <= study[0] <= 364 and study[1] in ("{}", {})
    migrate.downgrade(db_url, "0009")
    assert _count(db_url, "trials") == 2
