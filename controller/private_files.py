"""Files and folders only their owner can read or write, whatever the umask.

A study's files hold what nobody else on the machine should read: password hashes and
participant data in the database, the device key, exported tables. A process's umask
(022 on most systems) would leave them readable by every local account, so these
helpers ask for the mode explicitly: folders 0700, files 0600. They live beside the
controller so that its own writers (report folders) and the server's can share them.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import TextIO

#: Owner only: read, write and enter.
PRIVATE_DIR = 0o700
#: Owner only: read and write.
PRIVATE_FILE = 0o600
#: The permission bits of the group and of everyone else.
OTHERS = stat.S_IRWXG | stat.S_IRWXO


def make_private_dir(path: Path) -> list[Path]:
    """Create `path` and its missing parents with mode 0700 (an existing folder is left
    as it is); returns the folders created, outermost first."""
    missing: list[Path] = []
    p = path
    while not os.path.lexists(p):
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    created = []
    for folder in reversed(missing):
        try:
            folder.mkdir(mode=PRIVATE_DIR)
        except FileExistsError:
            continue  # another process made it first; its mode is its own
        os.chmod(folder, PRIVATE_DIR)  # mkdir's mode passes through the umask
        created.append(folder)
    return created


def write_private(path: Path, data: str | bytes) -> None:
    """Write `data` to `path` with mode 0600 (a file already there is made 0600 too
    before anything is written into it)."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0),
                 PRIVATE_FILE)
    try:
        os.fchmod(fd, PRIVATE_FILE)
        view = memoryview(raw)
        while view:
            view = view[os.write(fd, view):]
    finally:
        os.close(fd)


def open_private(path: Path) -> TextIO:
    """Open `path` for writing text with mode 0600 (truncated; a file already there is
    made 0600 first): for a log written as it goes, which `write_private` cannot do."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0),
                 PRIVATE_FILE)
    try:
        os.fchmod(fd, PRIVATE_FILE)
    except BaseException:
        os.close(fd)
        raise
    return open(fd, "w", encoding="utf-8")


def private_folder(path: Path) -> Path:
    """`path` as a folder only its owner may use: created 0700 (with missing parents),
    or, already there, with every permission of the group and of others taken off."""
    make_private_dir(path)
    tighten(path)
    return path


def create_private_file(path: Path) -> bool:
    """Create `path` empty with mode 0600 if nothing is there; True if it was created."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, PRIVATE_FILE)
    except FileExistsError:
        return False
    try:
        os.fchmod(fd, PRIVATE_FILE)
    finally:
        os.close(fd)
    return True


def open_to_others(path: Path) -> int | None:
    """The mode of `path` if its group or others have any permission on it, else None
    (also None for a missing path or a symbolic link, whose own mode means nothing)."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    if stat.S_ISLNK(st.st_mode) or not st.st_mode & OTHERS:
        return None
    return stat.S_IMODE(st.st_mode)


def tighten(path: Path) -> tuple[int, int] | None:
    """Take every permission of the group and of others off `path` (the owner's stay);
    returns (old mode, new mode), or None when there was nothing to take off."""
    mode = open_to_others(path)
    if mode is None:
        return None
    new = mode & ~OTHERS
    os.chmod(path, new)
    return mode, new
