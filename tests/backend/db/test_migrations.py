"""Migrations: up and down on an empty database, and the result matches the models."""

from __future__ import annotations

import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import inspect

from backend.db import migrate
from backend.db.engine import make_engine
from backend.db.tables import Base
from controller.tick_record import TickRecord


def test_upgrade_head_then_downgrade_base(db_url: str) -> None:
    migrate.upgrade(db_url)
    assert migrate.current(db_url) is not None
    engine = make_engine(db_url)
    assert {"runs", "ticks", "recordings", "trials", "participants"} <= set(
        inspect(engine).get_table_names()
    )
    migrate.downgrade(db_url)
    assert migrate.current(db_url) is None
    assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
    engine.dispose()


def test_migrated_schema_equals_the_models(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    engine.dispose()
    assert diff == []


def test_every_tick_field_is_a_column(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    cols = {c["name"] for c in inspect(engine).get_columns("ticks")}
    engine.dispose()
    assert set(TickRecord.field_names()) <= cols


def test_wal_and_foreign_keys_are_on(db_url: str) -> None:
    if not db_url.startswith("sqlite"):
        pytest.skip("SQLite connection pragmas; PostgreSQL has neither setting")
    engine = make_engine(db_url)
    with engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
    engine.dispose()
