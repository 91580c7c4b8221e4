"""Fixtures shared by the whole suite: a fresh migrated SQLite file and settings for it."""

from __future__ import annotations

from pathlib import Path

import pytest

from backend.core.config import Settings


@pytest.fixture(scope="session")
def default_sets(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The embedded default model set and utility folder, built once per test session
    (by the same code a first `make run` uses)."""
    from backend import bootstrap

    folder = tmp_path_factory.mktemp("defaults")
    models = folder / "models.json"
    bootstrap.ensure_models(models)
    bootstrap.ensure_utilities(bootstrap.utilities_path(folder, 25.0), 25.0)
    return models, folder


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    """A new SQLite file per test (migrations are applied by whoever opens it)."""
    return f"sqlite:///{tmp_path / 'exostudy.db'}"


@pytest.fixture
def settings(db_url: str, default_sets: tuple[Path, Path]) -> Settings:
    """Embedded defaults on a fresh database, without starting a worker."""
    models, folder = default_sets
    return Settings(  # type: ignore[call-arg]
        database_url=db_url, start_worker=False, models_path=models, utilities_dir=folder,
        device_kind="sim", _env_file=None,
    )
