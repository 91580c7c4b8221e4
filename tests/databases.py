"""Fresh test databases: a SQLite file by default, or a new database on the PostgreSQL
server `EXOSTUDY_DATABASE_URL` points at (created for the test, dropped after it)."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def postgres_server() -> str | None:
    """The PostgreSQL URL the suite should run against, if any."""
    url = os.environ.get("EXOSTUDY_DATABASE_URL", "")
    return url if url.startswith("postgresql") else None


@contextmanager
def fresh_database(folder: Path) -> Iterator[str]:
    """The URL of a new, empty database; SQLite lives in `folder`."""
    server = postgres_server()
    if server is None:
        yield f"sqlite:///{folder / 'exostudy.db'}"
        return
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url

    name = f"exostudy_test_{uuid.uuid4().hex[:16]}"
    admin = create_engine(server, isolation_level="AUTOCOMMIT")
    with admin.connect() as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    try:
        yield make_url(server).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()
