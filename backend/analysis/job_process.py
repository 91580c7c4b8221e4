"""A long job's computation in a child process: it runs beside the server's threads (not
under their interpreter lock, so a model fit queued meanwhile runs at its own speed),
and cancelling it is immediate (the child is terminated) instead of waiting for the
next progress report. A child also dies with the server, even one killed by SIGKILL.

The target must be a module-level function `target(*args, progress) -> result`, with
picklable arguments and result (the child is spawned: a fresh interpreter).
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import threading
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any, TypeVar

from backend.analysis.jobs import JobCancelledError, Progress

T = TypeVar("T")

#: How often the parent checks for cancellation while the child computes.
POLL_S = 0.1
#: How long a terminated child gets to exit before SIGKILL.
TERMINATE_WAIT_S = 2.0
#: linux/prctl.h
_PR_SET_PDEATHSIG = 1


class JobProcessError(RuntimeError):
    """The child failed (its exception, as text) or died without an answer."""


def _die_with_parent(parent_pid: int) -> None:
    """Ask the kernel for SIGTERM when the server dies (Linux); exit now if it already
    has. The server's job thread that started this child outlives it, so the signal
    comes only with the server's end."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):
        pass  # elsewhere: a child whose pipe breaks still ends at its next report
    if os.getppid() != parent_pid:
        raise SystemExit(4)


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
    """`target(*args, progress)` in a spawned child; its progress reports are passed to
    `progress` (which may raise `JobCancelledError`). Raises `JobCancelledError` once `cancelled`
    is set (the child is terminated), `JobProcessError` if the child fails or dies."""
    ctx = mp.get_context("spawn")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(target, args, send, os.getpid()),
                       name="exostudy-job", daemon=True)
    proc.start()
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
