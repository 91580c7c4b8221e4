"""Fixtures shared by the whole suite: a fresh migrated SQLite file and settings for it."""

from __future__ import annotations

from pathlib import Path

import pytest

from backend.core.config import Settings


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    """A new SQLite file per test (migrations are applied by whoever opens it)."""
    return f"sqlite:///{tmp_path / 'exostudy.db'}"


@pytest.fixture
def settings(db_url: str) -> Settings:
    """Embedded defaults on a fresh database, without starting a worker."""
    return Settings(database_url=db_url, start_worker=False, _env_file=None)  # type: ignore[call-arg]
