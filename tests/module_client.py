"""One logged-in app for a whole test module, for tests that only read from it.

Building the app costs 0.3 to 0.5 s of CPU (FastAPI resolves the dependencies and
models of its 170-odd routes for each app), and starting it migrates or checks the
database: about 0.8 s a test with the `client` fixture, which every test gets afresh
because most of them write and count rows. Tests that only read (headers, refusals,
served files) share this one instead; tests that write keep their own.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.main import create_app
from tests.databases import AccountTemplates, fresh_database, postgres_server
from tests.login import PASSWORD, USERNAME, create_experimenter, log_in


def module_engines() -> list[str]:
    """The engines a database-facing module's shared app runs on, as `tests/conftest.py`
    parametrizes `db_url`: SQLite and the throwaway PostgreSQL cluster, or only the
    server `EXOSTUDY_DATABASE_URL` names, or only SQLite with
    `EXOSTUDY_TEST_DATABASES=sqlite`."""
    wanted = os.environ.get("EXOSTUDY_TEST_DATABASES", "sqlite,postgresql").split(",")
    if postgres_server() is None and "postgresql" in wanted:
        return ["sqlite", "postgresql"]
    return ["sqlite"]


@contextmanager
def logged_in_client(folder: Path, default_sets: tuple[Path, Path],
                     templates: AccountTemplates, server: str | None = None
                     ) -> Iterator[TestClient]:
    """What the `client` fixture gives (a fresh database holding the experimenter, the
    app without worker or simulated device, logged in), once for the caller's scope;
    on the PostgreSQL `server` when given."""
    models, sets_folder = default_sets
    server = server or postgres_server()
    with fresh_database(folder, server) as url:
        creds = {"username": USERNAME, "password": PASSWORD}
        if not templates.fill(url, server):
            creds = create_experimenter(url)
        settings = Settings(  # type: ignore[call-arg]
            database_url=url, start_worker=False, models_path=models,
            utilities_dir=sets_folder, device_kind="sim", demo=False,
            device_spawn_simulator=False, _env_file=None)
        with TestClient(create_app(settings)) as client:
            log_in(client, creds)
            yield client
