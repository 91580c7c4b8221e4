"""A long job's computation in a child process: it runs beside the server's threads (not
under their interpreter lock, so a model fit queued meanwhile runs at its own speed),
and cancelling it is immediate (the child is terminated) instead of waiting for the
next progress report. A child also dies with the server, even one killed by SIGKILL.

The target must be a module-level function `target(*args, progress) -> result`, with
picklable arguments and result. The child is forked from the server's fork server, as
the worker is (`backend.worker.child_processes`): a fresh interpreter's imports cost each
job a second and a half of CPU.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any, TypeVar

from backend.analysis.jobs import JobCancelledError, Progress
from backend.worker import child_processes
from backend.worker.child_processes import ParentWatch

T = TypeVar("T")

#: How often the parent checks for cancellation while the child computes.
POLL_S = 0.1
#: How long a terminated child gets to exit before SIGKILL.
TERMINATE_WAIT_S = 2.0
#: How often a child looks whether its server is still there.
WATCH_S = 0.2


class JobProcessError(RuntimeError):
    """The child failed (its exception, as text) or died without an answer."""


def _die_with_parent(parent_pid: int) -> None:
    """End this child (SIGTERM to itself) once the server has gone; exit now if it
    already has. A thread watches, since the child's parent is the fork server, which
    outlives the server while children live (no parent-death signal can tell)."""
    parent = ParentWatch(parent_pid)
    if parent.gone():
        raise SystemExit(4)

    def watch() -> None:
        while not parent.gone():
            time.sleep(WATCH_S)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=watch, name="server-watch", daemon=True).start()


def _child(target: Callable[..., Any], args: tuple[Any, ...], conn: Connection,
           parent_pid: int) -> None:
    _die_with_parent(parent_pid)
    # Ctrl-C in a terminal reaches the whole process group: the server decides.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        result = target(*args, lambda f: conn.send(("progress", float(f))))
    except (BrokenPipeError, EOFError):
        raise SystemExit(3) from None  # the server is gone: nobody wants the answer
    except Exception as exc:
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    conn.send(("result", result))


def run_in_child(target: Callable[..., T], args: tuple[Any, ...], progress: Progress,
                 cancelled: threading.Event) -> T:
    """`target(*args, progress)` in a child process; its progress reports are passed to
    `progress` (which may raise `JobCancelledError`). Raises `JobCancelledError` once `cancelled`
    is set (the child is terminated), `JobProcessError` if the child fails or dies."""
    receive, send = child_processes.context().Pipe(duplex=False)
    proc = child_processes.start(_child, (target, args, send, os.getpid()), "exostudy-job")
    send.close()
    try:
        while True:
            if cancelled.is_set():
                raise JobCancelledError("cancelled")
            if not receive.poll(POLL_S):
                if not proc.is_alive() and not receive.poll():
                    raise JobProcessError(f"the job's process ended (exit code "
                                          f"{proc.exitcode}) without a result")
                continue
            try:
                kind, value = receive.recv()
            except EOFError:
                proc.join(TERMINATE_WAIT_S)
                raise JobProcessError(f"the job's process ended (exit code "
                                      f"{proc.exitcode}) without a result") from None
            if kind == "progress":
                progress(value)
            elif kind == "error":
                raise JobProcessError(str(value))
            else:
                return value
    finally:
        if proc.is_alive():
            proc.terminate()
            proc.join(TERMINATE_WAIT_S)
            if proc.is_alive():
                proc.kill()
        proc.join(TERMINATE_WAIT_S)
        receive.close()
