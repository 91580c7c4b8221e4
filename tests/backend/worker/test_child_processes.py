"""The server's Python children, forked from its fork server: they see the server's
environment as it is when they start, and they notice when the server has gone,
although their parent is the fork server."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from backend.worker import child_processes
from backend.worker.child_processes import ParentWatch
from tests.backend.worker import child_targets


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        with open(f"/proc/{pid}/stat") as f:  # a zombie (exited, not reaped) is gone too
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


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
    root = Path(__file__).resolve().parents[3]
    server = subprocess.Popen([sys.executable, "-m", "tests.backend.worker.child_targets",
                               str(out)], cwd=root)
    try:
        end = time.monotonic() + 60
        while not (tmp_path / "watch.ready").exists():
            assert server.poll() is None and time.monotonic() < end, "no child started"
            time.sleep(0.05)
        child, fork_server = map(int, (tmp_path / "watch.ready").read_text().split())
        os.kill(fork_server, signal.SIGKILL)
        end = time.monotonic() + 30
        while not out.exists():
            assert time.monotonic() < end, "the child outlived its fork server"
            time.sleep(0.05)
        assert out.read_text() == "gone" and server.poll() is None  # the server lives on
        while _alive(child):
            assert time.monotonic() < end + 30, "the child did not exit"
            time.sleep(0.05)
    finally:
        server.kill()
        server.wait(10)


def test_a_child_notices_its_server_killed(tmp_path: Path) -> None:
    out = tmp_path / "watch"
    root = Path(__file__).resolve().parents[3]
    server = subprocess.Popen([sys.executable, "-m", "tests.backend.worker.child_targets",
                               str(out)], cwd=root)
    try:
        end = time.monotonic() + 60
        while not (tmp_path / "watch.ready").exists():
            assert server.poll() is None and time.monotonic() < end, "no child started"
            time.sleep(0.05)
        assert not out.exists()  # the server lives: not gone
        child, fork_server = map(int, (tmp_path / "watch.ready").read_text().split())
        assert fork_server != server.pid
        os.kill(server.pid, signal.SIGKILL)  # no clean-up: the fork server's pipe closes
        server.wait(10)
        end = time.monotonic() + 30
        while not out.exists():
            assert time.monotonic() < end, "the child never noticed its server had gone"
            time.sleep(0.05)
        assert out.read_text() == "gone"
        # The child leaves, and with the last of its children the fork server: no orphan.
        end = time.monotonic() + 30
        while _alive(child) or _alive(fork_server):
            assert time.monotonic() < end, "an orphan outlived the server"
            time.sleep(0.05)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait(10)
