"""How the server starts its Python children (the worker, analysis jobs): forked from a
process that has already imported what the worker needs ("forkserver"), not each a
fresh interpreter ("spawn").

A fresh interpreter spent about 1.5 s of CPU importing NumPy, SciPy, numba, pydantic
and the controller before the worker's first tick, at every start and restart of the
worker: on a quiet 2-core machine, six starts of a worker with the simulator took
14.6 s of CPU and 1.5-1.8 s each to the first tick when spawned, 6.3 s and 0.3 s each
after the first when forked (process accounting). The fork
server is itself a fresh interpreter, started once per server (at its first child), that
only imports `PRELOAD`: it holds no threads, devices, database connections or sockets,
so a child forked from it starts from what "spawn" would have built, minus the waiting.
A job (`backend.analysis.job_process`) imports what it needs beyond the worker's after
the fork: preloading it would delay the worker's first start.

Two things "spawn" gave for free are kept by hand:
- the environment: the fork server's is the server's at the fork server's start, so
  every child takes the server's environment as it is when the child starts (`start`
  passes it, `_enter` applies it before the child runs anything). What a module reads
  from the environment when it is imported (numba's settings, the time zone) is still
  the fork server's: nothing in `backend` or `controller` does so;
- the parent: a child's parent is the fork server, not the server, and the fork server
  lives on while any child does, so a child watches the server itself (`ParentWatch`).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import select
from collections.abc import Callable
from multiprocessing.context import ForkServerContext
from multiprocessing.process import BaseProcess
from typing import Any

#: What the fork server imports once: the worker with its control loop and compiled
#: tick, and the in-process simulator most workers drive. Modules only, no state.
PRELOAD = ("backend.worker.process", "controller.sim.simulated_device")

_context: ForkServerContext | None = None


def context() -> ForkServerContext:
    """The start method of the server's Python children (their pipes come from it too)."""
    global _context
    if _context is None:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(list(PRELOAD))
        _context = ctx
    return _context


def start(target: Callable[..., Any], args: tuple[Any, ...], name: str) -> BaseProcess:
    """Start `target(*args)` in a child that sees this process's environment as it is
    now; a daemon, so it never outlives the server's interpreter."""
    proc = context().Process(target=_enter, args=(dict(os.environ), target, args),
                             name=name, daemon=True)
    proc.start()
    return proc


def _enter(environment: dict[str, str], target: Callable[..., Any],
           args: tuple[Any, ...]) -> None:
    os.environ.clear()
    os.environ.update(environment)
    target(*args)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # a process of another user holds the pid: it exists
    return True


class ParentWatch:
    """Whether the server that started this child is gone, or can no longer supervise it.

    A child of the fork server cannot watch its parent alone: the fork server outlives
    the server while any of its children lives (each holds the pipe it waits on). So a
    child whose parent is not the server holds a handle on the server itself (a pidfd on
    Linux, which a reused pid cannot fool; elsewhere its pid), taken at its start, when
    the server has just started it. A child of the server itself watches its parent, as
    before.

    The fork server's own end counts as gone too (its pid is the parent): the server
    learns a child's exit only through the fork server, so a child that lived on after
    it could drive the device unsupervised, and a restarted worker beside it would be a
    second one. Such a child releases and leaves; the server sees its worker gone (exit
    code 255: the status went with the fork server) and a restart starts a new fork
    server (`tests/backend/worker/test_child_processes.py`)."""

    def __init__(self, server_pid: int) -> None:
        self.server_pid = server_pid
        self._parent = os.getppid()
        self._pidfd: int | None = None
        self._gone = False
        if self._parent != server_pid:
            try:
                self._pidfd = os.pidfd_open(server_pid)
            except ProcessLookupError:
                self._gone = True
            except (AttributeError, OSError):
                self._gone = not _alive(server_pid)  # no pidfd here: poll the pid

    def gone(self) -> bool:
        """True once the server has gone (a system call or two: cheap at every tick)."""
        if self._gone or os.getppid() != self._parent:
            self._gone = True
        elif self._pidfd is not None:
            self._gone = bool(select.select([self._pidfd], [], [], 0)[0])
        elif self._parent != self.server_pid:
            self._gone = not _alive(self.server_pid)
        return self._gone
