"""The spawned simulator's bookkeeping: which ports are taken, which pids are ours."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from backend.live import device_process


def test_a_bound_udp_port_is_seen() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        assert device_process.udp_port_bound(port)
    assert not device_process.udp_port_bound(port)


def test_reclaim_never_kills_a_process_that_is_not_the_simulator(tmp_path: Path) -> None:
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        pid_file = tmp_path / "device-sim-5555.pid"
        pid_file.write_text(f"{other.pid}\n")  # a reused pid, say
        assert device_process.reclaim(pid_file, 5555) is None
        assert other.poll() is None and not pid_file.exists()
    finally:
        other.kill()
        other.wait()


def test_a_simulator_that_exits_at_once_is_an_error_with_its_message(tmp_path: Path) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        with pytest.raises(device_process.DeviceStartError, match="in use"):
            device_process.spawn(["--port", str(port)], port, tmp_path / "p.pid",
                                 tmp_path / "log")
    # A bad argument: the child's own complaint comes back.
    with pytest.raises(device_process.DeviceStartError, match="exited with code"):
        device_process.spawn(["--no-such-option"], port, tmp_path / "p.pid", tmp_path / "log")
    assert not (tmp_path / "p.pid").exists()


def test_die_with_parent_is_a_no_op_outside_a_spawned_simulator(monkeypatch:
                                                                 pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(device_process.PARENT_ENV, raising=False)
    device_process.die_with_parent()
    monkeypatch.setenv(device_process.PARENT_ENV, str(os.getppid() + 10**6))
    with pytest.raises(SystemExit):
        device_process.die_with_parent()
