"""Migration 0002 (study records) goes up and down on its own, leaving 0001's tables."""

from __future__ import annotations

from sqlalchemy import inspect

from backend.db import migrate
from backend.db.engine import make_engine

STUDY_TABLES = {
    "users", "auth_tokens", "studies", "participants", "condition_labels", "study_sessions",
    "questionnaire_instruments", "participant_links", "questionnaire_responses",
    "preferences", "audit_log",
}


def test_0002_up_and_down(db_url: str) -> None:
    engine = make_engine(db_url)
    migrate.upgrade(db_url, "0002")
    assert set(inspect(engine).get_table_names()) >= STUDY_TABLES
    migrate.downgrade(db_url, "0001")
    tables = set(inspect(engine).get_table_names())
    assert not STUDY_TABLES & tables and {"runs", "ticks"} <= tables
    migrate.upgrade(db_url)
    assert set(inspect(engine).get_table_names()) >= STUDY_TABLES
    engine.dispose()
