"""Alembic environment: the URL comes from the caller or from ExoStudy's settings;
batch mode because SQLite cannot ALTER most things."""

from __future__ import annotations

from alembic import context

from backend.core.config import get_settings
from backend.db.engine import make_engine
from backend.db.tables import Base

config = context.config
url = config.get_main_option("sqlalchemy.url") or get_settings().database_url


def run_offline() -> None:
    """Emit SQL without a connection (`alembic upgrade head --sql`)."""
    context.configure(url=url, target_metadata=Base.metadata, render_as_batch=True,
                      literal_binds=True)
    with context.begin_transaction():
        context.run_migrations()


def run_online() -> None:
    """Apply migrations on a live connection."""
    connectable = config.attributes.get("connection")
    if connectable is not None:
        context.configure(connection=connectable, target_metadata=Base.metadata,
                          render_as_batch=True)
        with context.begin_transaction():
            context.run_migrations()
        return
    engine = make_engine(url)
    with engine.connect() as connection:
        sqlite = connection.dialect.name == "sqlite"
        if sqlite:
            # Batch mode rebuilds a table (copy, drop, rename); with foreign keys on, the
            # drop would cascade and delete every child row (a study's participants,
            # sessions and trials). Off for the migration (a PRAGMA outside any
            # transaction), then checked and back on.
            connection.exec_driver_sql("PRAGMA foreign_keys=OFF")
            # The statement began a transaction; ended here, Alembic begins and commits
            # its own (it never commits one it finds open, and closing rolls it back).
            connection.commit()
        context.configure(connection=connection, target_metadata=Base.metadata,
                          render_as_batch=True)
        with context.begin_transaction():
            context.run_migrations()
        if sqlite:
            broken = connection.exec_driver_sql("PRAGMA foreign_key_check").fetchall()
            connection.exec_driver_sql("PRAGMA foreign_keys=ON")
            if broken:
                raise RuntimeError(f"the migration left rows without their parent: {broken[:5]}")
    engine.dispose()


if context.is_offline_mode():
    run_offline()
else:
    run_online()
