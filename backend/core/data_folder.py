"""The data folder is private: 0700, with the database and its companions 0600.

The database holds argon2 password hashes, participant data and the audit trail; the
folder beside it the device key, pid files and replication reports. With the usual
umask (022) SQLite would create `exostudy.db` 0644 in a 0755 folder, readable by every
local account. SQLite gives its `-wal`, `-shm` and `-journal` files the mode of the
database file, so creating that file 0600 before SQLite first opens it is enough for all
four. At every server start, older installations are brought to the same modes (the
folder, the files directly in it, the database's files), and the log says what changed.
`exostudy doctor` reports whatever is still open to others, down the whole tree of the
data folder (bounded, without following symbolic links).

"Ours" are the data folder (`EXOSTUDY_DATA_DIR`, `var/` in a clone) and `run_dir`:
their modes are set. A folder chosen elsewhere for the database or the key (the home
folder, a shared disk) keeps its mode; only a warning names it.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import chain
from pathlib import Path

from sqlalchemy.engine import make_url

from backend.core import config
from backend.core.config import Settings
from controller.private_files import (
    create_private_file,
    make_private_dir,
    open_to_others,
    tighten,
)

log = logging.getLogger(__name__)

#: What SQLite keeps beside a database file: write-ahead log, shared memory, rollback
#: journal.
SQLITE_COMPANIONS = ("-wal", "-shm", "-journal")


def sqlite_file(url: str) -> Path | None:
    """The database file of a SQLite URL (None for another database or in memory)."""
    parsed = make_url(url)
    if parsed.get_backend_name() != "sqlite":
        return None
    database = parsed.database
    if not database or database == ":memory:" or database.startswith("file:"):
        return None
    return Path(database)


def sqlite_files(url: str) -> list[Path]:
    """The database file of a SQLite URL and its companions (empty for PostgreSQL)."""
    path = sqlite_file(url)
    if path is None:
        return []
    return [path, *(path.with_name(path.name + s) for s in SQLITE_COMPANIONS)]


def prepare_sqlite(url: str) -> None:
    """Before SQLite first opens a file database: its folder created 0700 if missing
    and the file created empty with mode 0600, so that SQLite (which gives its WAL,
    shared-memory and journal files the database file's mode) makes all of them 0600.
    An existing file is left alone (it may be someone else's, opened read-only)."""
    path = sqlite_file(url)
    if path is None:
        return
    make_private_dir(path.parent)
    create_private_file(path)


def own_folders(settings: Settings) -> list[Path]:
    """The folders whose modes the server sets: the data folder and `run_dir`."""
    out: list[Path] = []
    for folder in (config.DATA_DIR, settings.run_dir):
        folder = Path(folder).absolute()
        if folder not in out:
            out.append(folder)
    return out


def _describe(path: Path, change: tuple[int, int]) -> str:
    return f"{path} {change[0]:o} -> {change[1]:o}"


def make_private(settings: Settings) -> list[str]:
    """At server start: the data folder and `run_dir` created 0700 or tightened, the
    files and folders directly in them and the database's files tightened (group and
    others lose every permission). Returns what changed, as `path old -> new`."""
    changed: list[str] = []

    def take(path: Path) -> None:
        try:
            change = tighten(path)
        except FileNotFoundError:  # removed meanwhile (a pid file of a stopped simulator)
            return
        except PermissionError as exc:  # not ours to change: doctor and the log say so
            log.warning("cannot make %s private: %s", path, exc)
            return
        if change is not None:
            changed.append(_describe(path, change))

    for folder in own_folders(settings):
        make_private_dir(folder)
        take(folder)
        with os.scandir(folder) as entries:
            for entry in entries:
                take(Path(entry.path))
    prepare_sqlite(settings.database_url)
    for path in sqlite_files(settings.database_url):
        take(path)
    return changed


#: Entries `exposures` looks at inside the data folders at most: the walk is bounded, so
#: a data folder of millions of files cannot stall `exostudy doctor` or a server start.
MAX_WALKED = 200_000
#: Paths named one by one; beyond these, exposures are counted.
MAX_LISTED = 50


@dataclass(frozen=True)
class Exposures:
    """What others may read or enter: the first `MAX_LISTED` as warning lines, the count
    of all found, and whether the walk stopped at `MAX_WALKED` entries."""

    listed: list[str]
    count: int
    walk_stopped: bool

    def lines(self) -> list[str]:
        """The warnings to print or log, with a line for what is only counted."""
        out = list(self.listed)
        if self.count > len(self.listed):
            out.append(f"... and {self.count - len(self.listed)} more paths open to others "
                       f"({self.count} in all, the first {len(self.listed)} listed); "
                       "`chmod -R go-rwx` on the data folder fixes them all")
        if self.walk_stopped:
            out.append(f"stopped looking after {MAX_WALKED} entries of the data folders: "
                       "there may be more")
        return out


def _tree(folder: Path, budget: list[int]) -> Iterator[Path]:
    """Every folder and file under `folder` (not `folder` itself), breadth first, not
    following symbolic links, until `budget[0]` entries have been seen."""
    pending = [folder]
    while pending and budget[0] > 0:
        here = pending.pop(0)
        try:
            with os.scandir(here) as entries:
                for entry in entries:
                    if budget[0] <= 0:
                        return
                    budget[0] -= 1
                    yield Path(entry.path)
                    if entry.is_dir(follow_symlinks=False):
                        pending.append(Path(entry.path))
        except (FileNotFoundError, NotADirectoryError, PermissionError):
            continue  # removed meanwhile, or not ours to read


def exposures(settings: Settings) -> Exposures:
    """What others on this machine may read or enter: each folder and file of the data
    (the data folder and `run_dir` with everything inside them, walked without following
    symbolic links; the database's folder and files; the device key and its folder)
    whose group or others have a permission, with its mode."""
    paths: list[Path] = []
    for folder in own_folders(settings):
        paths.append(folder)
    db_files = sqlite_files(settings.database_url)
    if db_files:
        paths.append(db_files[0].parent.absolute())
        paths.extend(p.absolute() for p in db_files)
    key = Path(settings.device_key_file).absolute()
    paths.extend([key.parent, key])
    budget = [MAX_WALKED]
    walked = (p for folder in own_folders(settings) if folder.is_dir()
              for p in _tree(folder, budget))
    listed: list[str] = []
    count = 0
    seen: set[Path] = set()
    for path in chain(paths, walked):
        if path in seen:
            continue
        seen.add(path)
        mode = open_to_others(path)
        if mode is None:
            continue
        count += 1
        if len(listed) < MAX_LISTED:
            kind = "folder" if path.is_dir() else "file"
            listed.append(f"{path}: {kind} readable or writable by others (mode {mode:o}); "
                          f"`chmod {'700' if kind == 'folder' else '600'} {path}`")
    return Exposures(listed, count, walk_stopped=budget[0] <= 0)
