"""A process's children as /proc lists them, for tests that follow the processes a
server starts (its fork server and what that forks)."""

from __future__ import annotations

from pathlib import Path


def thread_children(pid: int | str) -> set[int]:
    """Children of `pid` started by any of its threads (`/proc/PID/task/PID/children`
    lists only the main thread's; a job lane's child is its lane thread's)."""
    found: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            found |= {int(x) for x in (task / "children").read_text().split()}
        except (FileNotFoundError, ProcessLookupError):
            continue
    return found


def fork_servers(pid: int | str) -> list[int]:
    """The multiprocessing fork servers among the children of `pid`."""
    found = []
    for child in sorted(thread_children(pid)):
        try:
            if b"multiprocessing.forkserver" in Path(f"/proc/{child}/cmdline").read_bytes():
                found.append(child)
        except (FileNotFoundError, ProcessLookupError):
            continue
    return found
