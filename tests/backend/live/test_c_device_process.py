"""The C device as the server spawns it (`device_implementation = "c"`): found or
clearly missing, holding its port, reclaimed by a later server, dying with its parent,
and printing the same statistics as the Python device on SIGTERM."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from backend.live import device_process
from backend.main import create_app
from controller.device.auth import create_key, load_key
from controller.device.base import LockCommand, Sample, Status
from controller.device.udp import UdpDevice
from controller.sim.device_server import ServerStats
from tests import c_device
from tests.login import log_in
from tests.polling import free_udp_port, wait_for


@pytest.fixture
def key_file(tmp_path: Path) -> Path:
    path = tmp_path / "device.key"
    create_key(path)
    return path


def test_a_missing_c_device_is_an_error_naming_how_to_build_it(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(device_process.C_DEVICE_ENV, str(tmp_path / "nothing"))
    with pytest.raises(device_process.DeviceStartError, match="EXOSTUDY_DEVICE_BINARY"):
        device_process.c_device_binary()
    monkeypatch.delenv(device_process.C_DEVICE_ENV)
    monkeypatch.setattr(device_process, "C_DEVICE_BUILD", tmp_path / "exostudy-device")
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(device_process.DeviceStartError,
                       match=r"make -C .*firmware/ports/linux-sim"):
        device_process.spawn(["--port", "1"], 1, tmp_path / "p.pid", tmp_path / "log",
                             implementation="c")
    with pytest.raises(device_process.DeviceStartError, match="'python' or 'c'"):
        device_process.device_command([], "rust")


def test_the_c_device_holds_its_port_and_a_later_server_reclaims_it(
        tmp_path: Path, key_file: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(device_process.C_DEVICE_ENV, str(c_device.device_binary()))
    port = free_udp_port()
    pid_file, log = tmp_path / "device.pid", tmp_path / "device.log"
    proc = device_process.spawn(["--port", str(port), "--script", "standing",
                                 "--key-file", str(key_file)], port, pid_file, log,
                                implementation="c")
    try:
        assert device_process.udp_port_bound(port)
        assert pid_file.read_text().strip() == str(proc.pid)
        bridge = _children(proc.pid)
        assert len(bridge) == 1  # the simulated wearer
        # A restarted server finds it through the pid file and stops it (SIGTERM).
        assert device_process.reclaim(pid_file, port) == proc.pid
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0 and not device_process.udp_port_bound(port)
    wait_for(lambda: not Path(f"/proc/{bridge[0]}").exists(), 10, "the wearer to exit")
    stats = json.loads([line for line in log.read_text().splitlines()
                        if line.startswith("{")][-1])
    assert stats["implementation"] == "c" and stats["samples_sent"] == 0
    # The same summary as the Python device: every key, with the same JSON types.
    python = ServerStats().summary()
    assert set(python) <= set(stats)
    assert {k: type(v) for k, v in python.items()} == {k: type(stats[k]) for k in python}
    assert stats["host"] == "" and stats["watchdog_releases"] == 0


def test_the_c_device_exits_if_its_parent_is_already_gone(key_file: Path) -> None:
    env = dict(os.environ, **{device_process.PARENT_ENV: str(os.getpid() + 10**6)})
    done = subprocess.run([str(c_device.device_binary()), "--port", str(free_udp_port()),
                           "--key-file", str(key_file)], env=env, capture_output=True,
                          timeout=30)
    assert done.returncode == 4


def test_the_c_device_refuses_a_key_file_others_can_read(key_file: Path) -> None:
    key_file.chmod(0o644)
    done = subprocess.run([str(c_device.device_binary()), "--port", str(free_udp_port()),
                           "--key-file", str(key_file)], capture_output=True, text=True,
                          timeout=30)
    assert done.returncode == 2 and "readable by others" in done.stderr


def _children(pid: int) -> list[int]:
    text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    return [int(p) for p in text.split()]


@pytest.mark.slow
def test_the_server_streams_from_the_c_device_and_restarts_it_for_a_new_simulation(
        settings: Settings, experimenter: dict[str, str], tmp_path: Path) -> None:
    c_device.build()
    port = free_udp_port()
    settings = settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
        "device_address": f"127.0.0.1:{port}", "device_implementation": "c",
        "run_dir": tmp_path, "device_key_file": tmp_path / "device.key",
    })
    with TestClient(create_app(settings)) as client:
        log_in(client, experimenter)
        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        first = runtime.device_process
        assert Path(f"/proc/{first.pid}/exe").resolve().name == "exostudy-device"
        wait_for(lambda: (b := client.get("/api/health").json())["status"] == "ok"
                 and b["worker"]["ticks"] > 100, 60, "100 ticks from the C device")

        r = client.post("/api/worker/simulation", json={"seed": 7, "script": "squat-sequence"})
        assert r.status_code == 200, r.text
        second = runtime.device_process
        assert second.pid != first.pid and first.poll() is not None
        argv = Path(f"/proc/{second.pid}/cmdline").read_bytes().split(b"\0")
        assert argv[argv.index(b"--seed") + 1] == b"7"
        assert argv[argv.index(b"--script") + 1] == b"squat-sequence"
        ticks = client.get("/api/health").json()["worker"]["ticks"]
        body = wait_for(lambda: (b := client.get("/api/health").json())["worker"]["ticks"]
                        > ticks + 100 and b, 60, "100 more ticks from the new C device")
        assert body["device"]["alive"] and body["device"]["link_drops"]["device_replay"] == 0
        assert body["device"]["link_drops"]["device_auth"] == 0


def _play(command: list[str], port: int, key_file: Path) -> tuple[list[Sample], dict[str, Any]]:
    """Run a device to the end of its script, answering every sample without a lock;
    every sample it sent, and its statistics."""
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    samples: list[Sample] = []
    try:
        wait_for(lambda: device_process.udp_port_bound(port) or proc.poll() is not None, 60,
                 "the device to bind its port")
        dev = UdpDevice("127.0.0.1", port, key=load_key(key_file))
        dev.open()
        try:
            while proc.poll() is None or dev_has_more(dev, samples):
                s = dev.read(0.5)
                if s is not None:
                    samples.append(s)
                    dev.send(LockCommand(s.seq, False, False))
        finally:
            dev.close()
        out, _ = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return samples, json.loads(out.strip().splitlines()[-1])


def dev_has_more(dev: UdpDevice, samples: list[Sample]) -> bool:
    """After the device exited: take what is still queued on the socket."""
    s = dev.read(0.2)
    if s is None:
        return False
    samples.append(s)
    return True


@pytest.mark.slow
def test_the_c_device_plays_the_same_wearer_as_the_python_device(key_file: Path) -> None:
    """Same seed and script, no lock commanded: the two devices send the same counts,
    status and ground truth, sample for sample, and both stop at the script's end."""
    args = ["--seed", "2", "--script", "hip-flex-left", "--no-loop", "--key-file",
            str(key_file)]
    ports = free_udp_port(), free_udp_port()
    commands = [
        [sys.executable, "-m", "controller.sim.device_server", "--port", str(ports[0]), *args],
        [str(c_device.device_binary()), "--port", str(ports[1]), *args,
         "--python", sys.executable],
    ]
    with ThreadPoolExecutor(2) as pool:
        (py, py_stats), (c, c_stats) = pool.map(_play, commands, ports, [key_file] * 2)
    assert len(py) == len(c) == py_stats["samples_sent"] == c_stats["samples_sent"] > 1000
    assert [s.seq for s in c] == list(range(len(c)))
    # The solenoid and watchdog bits depend on when commands arrived; the rest may not.
    timing = Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT | Status.WATCHDOG_RELEASED

    def seen(s: Sample) -> tuple[object, ...]:
        t = s.truth
        assert t is not None
        progress = None if math.isnan(t.progress) else t.progress  # NaN != NaN
        return s.seq, s.t, s.counts, s.status & ~timing, t.activity, t.lift_index, progress

    assert [seen(s) for s in c] == [seen(s) for s in py]
    assert not any(s.status & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT) for s in c)
    assert len({s.counts for s in c}) > 100  # the wearer moved
