"""The server's Python children, forked from its fork server: they see the server's
environment as it is when they start, and they notice when the server has gone,
although their parent is the fork server."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from backend.worker import child_processes
from backend.worker.child_processes import ParentWatch
from tests.backend.worker import child_targets
from tests.faults.served import alive
from tests.polling import wait_for


@contextmanager
def _stand_in_server(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[bytes], int, int]]:
    """A stand-in server whose child, forked by its fork server, writes `watch` once it
    counts the server gone: the server, the child's pid and the fork server's."""
    ready = tmp_path / "watch.ready"
    root = Path(__file__).resolve().parents[3]
    server = subprocess.Popen([sys.executable, "-m", "tests.backend.worker.child_targets",
                               str(tmp_path / "watch")], cwd=root)
    try:
        wait_for(lambda: ready.exists() or server.poll() is not None, 60, "the child's start")
        assert server.poll() is None, "no child started"
        child, fork_server = map(int, ready.read_text().split())
        yield server, child, fork_server
    finally:
        if server.poll() is None:
            server.kill()
        server.wait(10)


def test_a_child_sees_the_environment_of_its_start_and_its_server_alive() -> None:
    ctx = child_processes.context()
    for value in ("first", "second"):  # the fork server started with neither
        os.environ["EXOSTUDY_CHILD_PROBE"] = value
        try:
            receive, send = ctx.Pipe(duplex=False)
            proc = child_processes.start(child_targets.report,
                                         (send, os.getpid(), "EXOSTUDY_CHILD_PROBE"), "probe")
            send.close()
            assert receive.poll(60), "the child did not report"
            pid, ppid, seen, gone = receive.recv()
            proc.join(10)
        finally:
            del os.environ["EXOSTUDY_CHILD_PROBE"]
        assert pid == proc.pid and proc.exitcode == 0
        assert ppid != os.getpid()  # forked by the fork server, not by this process
        assert seen == value and gone is False


def test_a_server_gone_before_the_child_looked_counts_as_gone() -> None:
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead = int(done.stdout)
    assert ParentWatch(dead).gone()  # neither this process's parent nor alive
    assert not ParentWatch(os.getppid()).gone()  # the parent itself, still there


def test_a_child_leaves_when_its_fork_server_dies_though_the_server_lives(
        tmp_path: Path) -> None:
    """Its exit status would go with the fork server: unsupervised, it releases and
    leaves rather than drive the device beside the worker a restart would start."""
    out = tmp_path / "watch"
    with _stand_in_server(tmp_path) as (server, child, fork_server):
        os.kill(fork_server, signal.SIGKILL)
        wait_for(out.exists, 30, "the child to leave after its fork server")
        assert out.read_text() == "gone" and server.poll() is None  # the server lives on
        wait_for(lambda: not alive(child), 30, "the child to exit")


def test_a_child_notices_its_server_killed(tmp_path: Path) -> None:
    out = tmp_path / "watch"
    with _stand_in_server(tmp_path) as (server, child, fork_server):
        assert not out.exists()  # the server lives: not gone
        assert fork_server != server.pid
        os.kill(server.pid, signal.SIGKILL)  # no clean-up: the fork server's pipe closes
        server.wait(10)
        wait_for(out.exists, 30, "the child to notice its server had gone")
        assert out.read_text() == "gone"
        # The child leaves, and with the last of its children the fork server: no orphan.
        wait_for(lambda: not (alive(child) or alive(fork_server)), 30,
                 "the orphans to exit")
