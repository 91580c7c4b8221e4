"""Targets the child-process tests run in a child of the fork server (importable by
name, as every child target must be)."""

from __future__ import annotations

import os
import sys
import time
from multiprocessing.connection import Connection
from pathlib import Path

from backend.worker import child_processes
from backend.worker.child_processes import ParentWatch


def _write_whole(path: str, text: str) -> None:
    """Write, then rename: the tests poll for the name, and must never read a file that
    exists but is still empty (a failure CI saw)."""
    partial = Path(path + ".partial")
    partial.write_text(text)
    partial.rename(path)


def report(conn: Connection, server_pid: int, name: str) -> None:
    """Send what the child sees: its parent, an environment variable, and whether its
    server counts as gone."""
    conn.send((os.getpid(), os.getppid(), os.environ.get(name),
               ParentWatch(server_pid).gone()))


def watch_until_gone(server_pid: int, out: str) -> None:
    """Write `gone` to `out` once the server has gone (at most 60 s)."""
    watch = ParentWatch(server_pid)
    _write_whole(out + ".ready", f"{os.getpid()} {os.getppid()}")
    end = time.monotonic() + 60
    while time.monotonic() < end:
        if watch.gone():
            _write_whole(out, "gone")
            return
        time.sleep(0.01)


def serve_one_child(out: str) -> None:
    """A stand-in server: start a watching child, then wait to be killed."""
    child_processes.start(watch_until_gone, (os.getpid(), out), "watcher")
    time.sleep(120)


if __name__ == "__main__":
    serve_one_child(sys.argv[1])
