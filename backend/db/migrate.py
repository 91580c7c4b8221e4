"""Apply or revert the Alembic migrations in `migrations/` programmatically."""

from __future__ import annotations

from alembic import command
from alembic.config import Config

from backend.core import resources


def alembic_config(database_url: str) -> Config:
    """An Alembic config pointing at the project's migrations and `database_url`."""
    cfg = Config()
    cfg.set_main_option("script_location", str(resources.migrations_dir()))
    # ConfigParser interpolation would choke on '%' in passwords.
    cfg.set_main_option("sqlalchemy.url", database_url.replace("%", "%%"))
    return cfg


def upgrade(database_url: str, revision: str = "head") -> None:
    """Bring the database to `revision` (default: the newest)."""
    command.upgrade(alembic_config(database_url), revision)


def downgrade(database_url: str, revision: str = "base") -> None:
    """Revert the database to `revision` (default: empty)."""
    command.downgrade(alembic_config(database_url), revision)


def current(database_url: str) -> str | None:
    """The revision the database is at, or None for an empty one."""
    from alembic.runtime.migration import MigrationContext

    from backend.db.engine import make_engine

    engine = make_engine(database_url)
    try:
        with engine.connect() as conn:
            return MigrationContext.configure(conn).get_current_revision()
    finally:
        engine.dispose()
