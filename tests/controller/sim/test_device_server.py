"""The simulated exoskeleton on the wire: pacing, commands, the watchdog, address filtering,
and the server in a real separate process talking to `UdpDevice` over loopback."""

from __future__ import annotations

import importlib.util
import json
import multiprocessing
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from controller.device.auth import create_key, tag
from controller.device.base import Device, LockCommand, Sample, Status
from controller.device.protocol import (
    CommandPacket,
    HelloPacket,
    decode_frame,
    decode_sample,
    encode_command,
    encode_hello,
)
from controller.device.udp import UdpDevice
from controller.sim.device_server import ServerStats, serve
from tests.controller.sim.stub_model import KEY, StubExoskeleton, serve_stub
from tests.polling import free_udp_port, wait_for

ROOT = Path(__file__).resolve().parents[3]
LOCK_BOTH = LockCommand(seq=0, lock_left=True, lock_right=True)
LOCK_LEFT = LockCommand(seq=0, lock_left=True, lock_right=False)


def _bound_ports() -> set[int]:
    """Local UDP ports in use, from the kernel's table (probing by binding would race)."""
    ports = set()
    for line in Path("/proc/net/udp").read_text().splitlines()[1:]:
        local = line.split()[1]
        ports.add(int(local.split(":")[1], 16))
    return ports


def _wait_bound(port: int, timeout: float = 5.0) -> None:
    """Until the server has bound its port (so the host's first HELLO is not lost)."""
    wait_for(lambda: port in _bound_ports(), timeout, f"a server bound to UDP port {port}",
             poll=0.01)


@dataclass
class Running:
    port: int
    model: StubExoskeleton
    stop: threading.Event
    thread: threading.Thread
    result: list[ServerStats] = field(default_factory=list)

    def finish(self) -> ServerStats:
        self.stop.set()
        self.thread.join(2.0)
        assert not self.thread.is_alive()
        return self.result[0]


def _start(model: StubExoskeleton | None = None, **kwargs: object) -> Running:
    port = free_udp_port()
    run = Running(port, model or StubExoskeleton(), threading.Event(), threading.Thread())

    def target() -> None:
        run.result.append(
            serve(port, 0, "stub", stop_event=run.stop, model=run.model, key=KEY,
                  **kwargs)  # type: ignore[arg-type]
        )

    run.thread = threading.Thread(target=target, daemon=True)
    run.thread.start()
    _wait_bound(port)
    return run


@pytest.fixture
def server() -> Iterator[Running]:
    run = _start()
    yield run
    run.stop.set()
    run.thread.join(2.0)


@pytest.fixture
def host(server: Running) -> Iterator[UdpDevice]:
    dev = UdpDevice(device_host="127.0.0.1", device_port=server.port, key=KEY)
    dev.open()
    yield dev
    dev.close()


def _read(dev: UdpDevice) -> Sample:
    s = dev.read(0.5)
    assert s is not None
    return s


def test_streams_at_100hz_after_hello(server: Running, host: UdpDevice) -> None:
    first = _read(host)
    got = [first] + [_read(host) for _ in range(49)]
    assert [s.seq for s in got] == list(range(50))
    assert [s.counts[0] for s in got] == list(range(50))  # warm-up did not advance the model
    assert [s.t for s in got] == pytest.approx([0.01 * k for k in range(50)])
    assert all(s.status & Status.WATCHDOG_RELEASED for s in got)  # no command yet
    assert not any(s.status & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT) for s in got)
    assert got[-1].truth is not None and got[-1].truth.activity == "squat"
    assert host.faults() == []


def test_lock_command_is_reflected(server: Running, host: UdpDevice) -> None:
    statuses = []
    for _ in range(30):
        statuses.append(_read(host).status)
        host.send(LOCK_LEFT)
    # A command applies from the next tick on.
    for st in statuses[2:]:
        assert st & Status.SOLENOID_LEFT and st & Status.LOCKED_LEFT
        assert not st & (Status.SOLENOID_RIGHT | Status.WATCHDOG_RELEASED)
    applied = [c for c in server.model.commands if c is not None and c.lock_left]
    assert len(applied) >= 28
    # The last command may still be in flight: stop the server only once a tick has
    # applied it (its sequence number is the host's latest), or it would go uncounted.
    last = host._host_seq
    wait_for(lambda: any(c is not None and c.seq == last for c in server.model.commands),
             5.0, f"a tick that applied the host's last command (seq {last})", poll=0.005)
    stats = server.finish()
    assert stats.commands == 30 and stats.stale_commands == 0
    assert len(stats.rtt_s) >= 28  # round trips were measured (their size: bench/bench_udp.py)


def test_watchdog_releases_within_100_to_130_ms(server: Running, host: UdpDevice) -> None:
    for _ in range(20):
        _read(host)
        host.send(LOCK_BOTH)
    last_command = time.monotonic()
    while True:
        s = _read(host)
        waited = time.monotonic() - last_command
        if s.status & Status.WATCHDOG_RELEASED:
            break
        assert s.status & Status.SOLENOID_LEFT and s.status & Status.SOLENOID_RIGHT
        assert waited < 0.2
    assert 0.100 <= waited <= 0.130
    assert not s.status & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT)
    assert server.finish().watchdog_releases == 1


def _raw_host(ip: str = "127.0.0.1") -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((ip, 0))
    sock.settimeout(0.5)
    return sock


def test_foreign_forged_and_malformed_commands_are_ignored(
    server: Running, host: UdpDevice,
) -> None:
    intruder = _raw_host("127.0.0.2")  # another loopback address
    with intruder:
        statuses = []
        for i in range(20):
            statuses.append(_read(host).status)
            device = host.device_sessions.current
            assert device is not None
            lock = encode_command(CommandPacket(10**6 + i, True, True), KEY, host.session,
                                  device)
            intruder.sendto(lock, ("127.0.0.1", server.port))  # right key, wrong address
            forged = encode_command(CommandPacket(10**6 + i, True, True), bytes(32),
                                    host.session, device)
            host._sendto(forged)  # from the host's own address, without the key
            old = bytearray(lock[:-32])
            old[2] = 1
            host._sendto(bytes(old) + tag(KEY, bytes(old)))  # authentic, another version
    assert all(st & Status.WATCHDOG_RELEASED for st in statuses)
    assert not any(st & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT) for st in statuses)
    # The device reports its drops in its samples: wait until the last forged one shows.
    deadline = time.monotonic() + 5.0
    while host.link_counters()["device_auth"] < 20 and time.monotonic() < deadline:
        _read(host)
    assert host.link_counters()["device_auth"] == 20
    stats = server.finish()
    assert stats.foreign == 20
    assert stats.malformed["auth"] == 20 and stats.summary()["unknown_version"] == 20
    assert stats.summary()["auth_failures"] == 20
    assert stats.commands == 0 and stats.host_changes == 0


def test_host_port_is_learned_and_stale_commands_dropped(server: Running) -> None:
    a, b = _raw_host(), _raw_host()
    b_port = b.getsockname()[1]
    dev = ("127.0.0.1", server.port)
    with a, b:
        a.sendto(encode_hello(HelloPacket(100), KEY, 0xA), dev)
        first = decode_frame(a.recv(2048), KEY)
        assert isinstance(first.packet, Sample) and first.packet.seq == 0
        assert first.receiver == 0xA
        d = first.sender
        a.sendto(encode_command(CommandPacket(101, True, False), KEY, 0xA, d), dev)
        a.sendto(encode_command(CommandPacket(99, False, False), KEY, 0xA, d), dev)
        a.sendto(encode_command(CommandPacket(101, True, True), KEY, 0xA, d), dev)  # replay
        a.sendto(encode_command(CommandPacket(102, True, True), KEY, 0xA, d ^ 1), dev)
        time.sleep(0.05)
        b.sendto(encode_hello(HelloPacket(1), KEY, 0xB), dev)  # a restarted host
        time.sleep(0.03)
        b_sample = decode_sample(b.recv(2048), KEY)
        assert b_sample.seq > 0  # the stream moved to the new port, same device clock
        a.sendto(encode_command(CommandPacket(103, True, True), KEY, 0xA, d), dev)  # retired
    time.sleep(0.03)
    stats = server.finish()
    assert stats.commands == 1 and stats.stale_commands == 1
    assert stats.replayed == 3  # seen, addressed to another boot, from a retired host
    assert stats.hellos == 2 and stats.host_changes == 1
    assert stats.host == f"127.0.0.1:{b_port}"


def test_duration_and_script_end_stop_the_server() -> None:
    t0 = time.monotonic()
    alone = serve(free_udp_port(), 0, "stub", duration=0.2, model=StubExoskeleton(), key=KEY)
    assert alone.samples_sent == 0
    assert 0.18 < time.monotonic() - t0 < 0.5  # nobody said hello: no samples, still stops
    run = _start(StubExoskeleton(steps=10), loop=False)
    dev = UdpDevice(device_port=run.port, key=KEY)
    dev.open()
    seqs = []
    while (s := dev.read(0.3)) is not None:
        seqs.append(s.seq)
    dev.close()
    run.thread.join(1.0)
    assert not run.thread.is_alive()
    assert seqs == list(range(10))
    assert run.result[0].samples_sent == 10


class _GlitchyModel(StubExoskeleton):
    """Produces one impossible encoder count at step 3."""

    def tick(self, command: LockCommand | None) -> Sample:
        sample = super().tick(command)
        if sample.seq == 3:
            return Sample(seq=3, t=0.03, counts=(20000, 0, 0, 0))
        return sample


def test_an_unencodable_sample_becomes_a_gap_not_a_crash() -> None:
    run = _start(_GlitchyModel())
    dev = UdpDevice(device_port=run.port, key=KEY)
    dev.open()
    seqs = [_read(dev).seq for _ in range(6)]
    dev.close()
    stats = run.finish()
    assert seqs == [0, 1, 2, 4, 5, 6]
    assert stats.send_errors == 1
    assert dev.stats.gaps == 1 and dev.stats.missing == 1


def _drive(dev: Device, seconds: float) -> tuple[list[float], list[Sample]]:
    """Play the worker: read each sample, answer at once (lock both after 1 s)."""
    arrivals: list[float] = []
    got: list[Sample] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        s = dev.read(0.5)
        assert s is not None
        arrivals.append(time.monotonic())
        got.append(s)
        dev.send(LOCK_BOTH if len(got) > 100 else LockCommand(0, False, False))
    return arrivals, got


def _check_stream(arrivals: list[float], got: list[Sample]) -> None:
    # Timing is for the benchmarks (bench/bench_udp.py); here: nothing lost, device
    # clock steps of 10 ms, commands applied.
    seqs = [s.seq for s in got]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # no loss on loopback
    assert [b.t - a.t for a, b in zip(got, got[1:], strict=False)] == pytest.approx(
        [0.01] * (len(got) - 1))
    both = Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT
    assert all(s.status & both == both for s in got[105:])
    assert not any(s.status & both for s in got[:100])


def _stub_process_run() -> tuple[list[float], list[Sample], dict[str, Any]]:
    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    port = free_udp_port()
    proc = ctx.Process(target=serve_stub, args=(port, 4.0, queue))
    proc.start()
    try:
        _wait_bound(port, timeout=20.0)
        with UdpDevice(device_port=port, key=KEY) as dev:
            assert dev.kind == "udp"
            arrivals, got = _drive(dev, 2.5)
        summary: dict[str, Any] = queue.get(timeout=10.0)
    finally:
        proc.join(10.0)
        if proc.is_alive():
            proc.terminate()
    return arrivals, got, summary


def test_server_in_a_separate_process_with_stub_model() -> None:
    arrivals, got, summary = _stub_process_run()
    _check_stream(arrivals, got)
    assert summary["rtt_n"] >= len(got) - 2
    assert summary["foreign"] == 0 and summary["malformed"] == {}


@pytest.mark.skipif(
    importlib.util.find_spec("controller.sim.exoskeleton") is None,
    reason="SimulatedExoskeleton not written yet",
)
def test_real_device_sim_process_over_loopback(tmp_path: Path) -> None:
    port = free_udp_port()
    key_file = tmp_path / "device.key"
    key = create_key(key_file)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "controller.sim.device_server",
            "--port",
            str(port),
            "--seed",
            "3",
            "--script",
            "paper-evaluation",
            "--key-file",
            str(key_file),
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    try:
        _wait_bound(port, timeout=30.0)
        with UdpDevice(device_port=port, key=key) as dev:
            arrivals, got = _drive(dev, 2.0)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10.0)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    _check_stream(arrivals, got)
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["samples_sent"] >= len(got)
    assert summary["commands"] >= len(got) - 2
    assert summary["host"].startswith("127.0.0.1:")
