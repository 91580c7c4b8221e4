"""The spawned simulator's bookkeeping: which ports are taken, which pids are ours."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path
from typing import Literal

import pytest

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.live import device_process
from backend.live.runtime import Runtime


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


@pytest.mark.parametrize("implementation", ["python", "c"])
def test_the_server_spawns_its_simulator_asking_for_real_time(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        implementation: Literal["python", "c"]) -> None:
    """Like the worker's loop, the simulated device asks for real-time scheduling, so
    it does not stall behind the server's start-up and call prompt commands stale."""
    settings = Settings(database_url=f"sqlite:///{tmp_path}/x.db", run_dir=tmp_path,  # type: ignore[call-arg]
                        device_key_file=tmp_path / "device.key",
                        device_implementation=implementation, _env_file=None)
    spawned: list[list[str]] = []

    def spawn(args: list[str], port: int, pid_file: Path, log_file: Path,
              implementation: str = "python") -> None:
        spawned.append(device_process.device_command(args, implementation))

    monkeypatch.setattr(device_process, "spawn", spawn)
    monkeypatch.setattr(device_process, "c_device_binary", lambda: Path("exostudy-device"))
    Runtime(settings, make_engine(settings.database_url)).start_device_simulator()
    assert len(spawned) == 1 and "--realtime" in spawned[0]
