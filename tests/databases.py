"""Fresh test databases: a SQLite file, or a new database on a PostgreSQL server (created
for the test, dropped after it).

The server is `EXOSTUDY_DATABASE_URL` when it points at PostgreSQL; otherwise, for the
database-facing tests, a throwaway cluster this module starts itself from Debian's
`postgresql` package (`initdb` and `pg_ctl` in a temporary folder, listening on a Unix
socket only, no system service), stopped and deleted at the end of the run.
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import tempfile
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def postgres_server() -> str | None:
    """The PostgreSQL URL the whole suite should run against, if any."""
    url = os.environ.get("EXOSTUDY_DATABASE_URL", "")
    return url if url.startswith("postgresql") else None


def _postgres_bin(name: str) -> str | None:
    """`initdb`/`pg_ctl` from PATH or Debian's versioned folder (newest first)."""
    found = shutil.which(name)
    if found:
        return found
    candidates = sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"),
                        key=lambda p: int(Path(p).parts[4]) if Path(p).parts[4].isdigit()
                        else 0, reverse=True)
    return candidates[0] if candidates else None


class ThrowawayCluster:
    """A PostgreSQL cluster in a temporary folder. PostgreSQL refuses to run as root, so
    under root it runs as the `postgres` account the Debian package creates."""

    def __init__(self) -> None:
        initdb, pg_ctl = _postgres_bin("initdb"), _postgres_bin("pg_ctl")
        if initdb is None or pg_ctl is None:
            raise RuntimeError("PostgreSQL's initdb/pg_ctl not found: `make test` installs "
                               "Debian's postgresql package")
        self.pg_ctl = pg_ctl
        self.folder = Path(tempfile.mkdtemp(prefix="exostudy-pg-"))
        self.data = self.folder / "data"
        self.socket_dir = self.folder / "socket"
        self.socket_dir.mkdir()
        self.port = 5432
        self._as: list[str] = []
        if os.geteuid() == 0:
            self._as = ["runuser", "-u", "postgres", "--"]
            shutil.chown(self.folder, "postgres")
            shutil.chown(self.socket_dir, "postgres")
        self._run([initdb, "-D", str(self.data), "-U", "exostudy", "-A", "trust",
                   "-E", "UTF8", "--no-sync", "--locale=C.UTF-8"])
        options = (f"-k {self.socket_dir} -p {self.port} -c listen_addresses='' "
                   "-c fsync=off -c synchronous_commit=off -c full_page_writes=off "
                   "-c max_connections=200")
        self._run([pg_ctl, "-D", str(self.data), "-o", options, "-w", "-t", "60",
                   "-l", str(self.folder / "server.log"), "start"])

    def _run(self, cmd: list[str]) -> None:
        done = subprocess.run([*self._as, *cmd], capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd[:2])} failed: {done.stderr or done.stdout}")

    @property
    def url(self) -> str:
        """SQLAlchemy URL of the cluster's maintenance database, over the socket."""
        return (f"postgresql+psycopg://exostudy@/postgres?host={self.socket_dir}"
                f"&port={self.port}")

    def stop(self) -> None:
        """Stop the server and delete the folder."""
        try:
            self._run([self.pg_ctl, "-D", str(self.data), "-m", "immediate", "stop"])
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


@contextmanager
def fresh_database(folder: Path, server: str | None = None) -> Iterator[str]:
    """The URL of a new, empty database: on `server` (or `postgres_server()`) when
    given, else a SQLite file in `folder`."""
    server = server or postgres_server()
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


class AccountTemplates:
    """Per test process and database server: one database migrated to head and holding
    the default experimenter account (built by `tests.login.create_experimenter`, the
    same code a test would run), copied into each test's new database instead of
    migrating it and hashing the password again (0.15 to 0.4 s a test, measured,
    for the hundreds of tests that log in).

    A SQLite template is a file copied over the test's not-yet-created file; a
    PostgreSQL template is a database that the test's empty database is re-created
    from (`CREATE DATABASE ... TEMPLATE`). A test database that is no longer empty is
    left alone, and the caller migrates it as before.
    """

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self._sqlite: Path | None = None
        self._postgres: dict[str, str] = {}

    def fill(self, db_url: str, server: str | None) -> bool:
        """Make the empty database at `db_url` a copy of the template; False when it was
        not empty (nothing is changed then)."""
        if db_url.startswith("sqlite"):
            return self._fill_sqlite(Path(db_url.removeprefix("sqlite:///")))
        if server is None:
            return False
        return self._fill_postgres(db_url, server)

    def _fill_sqlite(self, path: Path) -> bool:
        if path.exists() and path.stat().st_size > 0:  # an engine creates it empty first
            return False
        if self._sqlite is None:
            import sqlite3

            from tests.login import create_experimenter

            template = self.folder / "template.db"
            create_experimenter(f"sqlite:///{template}")
            # Everything into the main file (WAL mode keeps recent pages beside it), so
            # that the file alone is the whole database.
            with sqlite3.connect(template) as conn:
                conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            conn.close()
            self._sqlite = template
        shutil.copyfile(self._sqlite, path)
        return True

    def _fill_postgres(self, db_url: str, server: str) -> bool:
        from sqlalchemy import create_engine, text
        from sqlalchemy.engine import make_url

        engine = create_engine(db_url)
        try:
            with engine.connect() as conn:
                tables = conn.execute(text(
                    "SELECT count(*) FROM information_schema.tables "
                    "WHERE table_schema = 'public'")).scalar_one()
        finally:
            engine.dispose()
        if tables:
            return False
        admin = create_engine(server, isolation_level="AUTOCOMMIT")
        try:
            template = self._postgres.get(server)
            if template is None:
                from tests.login import create_experimenter

                template = f"exostudy_template_{uuid.uuid4().hex[:16]}"
                with admin.connect() as conn:
                    conn.execute(text(f'CREATE DATABASE "{template}"'))
                create_experimenter(
                    make_url(server).set(database=template).render_as_string(
                        hide_password=False))
                self._postgres[server] = template
            name = make_url(db_url).database
            with admin.connect() as conn:
                conn.execute(text(f'DROP DATABASE "{name}" WITH (FORCE)'))
                conn.execute(text(f'CREATE DATABASE "{name}" TEMPLATE "{template}"'))
        finally:
            admin.dispose()
        return True

    def drop(self) -> None:
        """Drop the PostgreSQL templates (the SQLite one goes with its folder)."""
        from sqlalchemy import create_engine, text
        from sqlalchemy.exc import OperationalError

        for server, template in self._postgres.items():
            admin = create_engine(server, isolation_level="AUTOCOMMIT")
            try:
                with admin.connect() as conn:
                    conn.execute(text(f'DROP DATABASE IF EXISTS "{template}" WITH (FORCE)'))
            except OperationalError:
                # The suite's throwaway cluster stops before this (a session fixture
                # started later ends earlier), and its templates go with it.
                if postgres_server() == server:
                    raise
            finally:
                admin.dispose()
        self._postgres.clear()
