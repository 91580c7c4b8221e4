"""Migration 0012 on a database with jobs in it: existing cohort jobs go to the cohort
lane, the others to the study lane, and nothing is lost going down again."""

from __future__ import annotations

from sqlalchemy import text

from backend.db import migrate
from backend.db.engine import make_engine


def test_existing_jobs_get_their_lane_and_survive_a_downgrade(db_url: str) -> None:
    migrate.upgrade(db_url, "0011")
    engine = make_engine(db_url)
    with engine.begin() as conn:
        for kind in ("cohort", "fit_model_set", "compute_utilities"):
            conn.execute(text("INSERT INTO jobs (kind, target_id, status, progress, message, "
                              "created_at) VALUES (:k, 1, 'done', 1.0, 'ok', "
                              "CURRENT_TIMESTAMP)"), {"k": kind})
    migrate.upgrade(db_url)
    with engine.connect() as conn:
        rows = conn.execute(text("SELECT kind, lane, created_by, started_at FROM jobs "
                                 "ORDER BY id")).all()
    assert [tuple(r) for r in rows] == [("cohort", "cohort", None, None),
                                        ("fit_model_set", "study", None, None),
                                        ("compute_utilities", "study", None, None)]
    migrate.downgrade(db_url, "0011")
    with engine.connect() as conn:
        kinds = conn.execute(text("SELECT kind, status FROM jobs ORDER BY id")).all()
    assert [tuple(r) for r in kinds] == [("cohort", "done"), ("fit_model_set", "done"),
                                         ("compute_utilities", "done")]
    engine.dispose()
