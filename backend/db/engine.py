"""Engine and sessions. SQLite gets WAL and foreign keys on every connection, so that the
tick writer and the API can work at the same time and references are enforced."""

from __future__ import annotations

from typing import Any

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session, sessionmaker

from backend.core.data_folder import prepare_sqlite


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.execute("PRAGMA busy_timeout=5000")
    cursor.close()


def make_engine(url: str) -> Engine:
    """An engine for `url`; a SQLite file and its folder are created private if missing."""
    parsed = make_url(url)
    kwargs: dict[str, Any] = {}
    if parsed.get_backend_name() == "sqlite":
        # Folder 0700 and file 0600 before SQLite makes them with the umask's modes
        # (its -wal and -shm files then take the file's mode: backend/core/data_folder.py).
        prepare_sqlite(url)
        kwargs["connect_args"] = {"check_same_thread": False}
    # A pool of 10 that may grow to 30: the analysis reads that hold two connections
    # each (`backend.api.deps.HEAVY_READS`) fit beside the ordinary requests, and two
    # engines (the API's and the tick writer's) stay well under PostgreSQL's default
    # of 100 connections.
    if parsed.database not in (None, "", ":memory:"):  # in-memory SQLite keeps one
        kwargs.update(pool_size=10, max_overflow=20)
    engine = create_engine(url, **kwargs)
    if parsed.get_backend_name() == "sqlite":
        event.listen(engine, "connect", _sqlite_pragmas)
    return engine


def make_session_factory(engine: Engine) -> sessionmaker[Session]:
    """Sessions that keep loaded objects usable after commit (responses read them)."""
    return sessionmaker(bind=engine, expire_on_commit=False)
