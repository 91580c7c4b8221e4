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
    ChallengePacket,
    CommandPacket,
    HelloPacket,
    JoinPacket,
    decode_frame,
    encode_command,
    encode_hello,
    encode_join,
)
from controller.device.udp import UdpDevice
from controller.sim.device_server import FIRMWARE, ServerStats, serve
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
    assert stats.commands == 30 and stats.drops["stale_echo"] == 0
    assert len(stats.rtt_s) >= 28  # round trips were measured (their size: bench/bench_udp.py)


def test_watchdog_releases_100_ms_after_the_echoed_sample(server: Running,
                                                          host: UdpDevice) -> None:
    """The last command holds the locks until 100 ms after the sample it echoes (device
    time), not 100 ms after it arrived: no energised sample is more than 100 ms younger
    than that sample, and the release comes by the next period."""
    for _ in range(20):
        echoed = _read(host)
        host.send(LOCK_BOTH)
    while True:
        s = _read(host)
        if s.status & Status.WATCHDOG_RELEASED:
            break
        assert s.status & Status.SOLENOID_LEFT and s.status & Status.SOLENOID_RIGHT
        assert s.t - echoed.t <= 0.100 + 1e-9
    # Released by 100 ms + one period after the echoed sample; not long before it
    # either (a tick woken late may release one period early: that is safe).
    assert 0.080 - 1e-9 <= s.t - echoed.t <= 0.110 + 1e-9
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
            sample = _read(host)
            statuses.append(sample.status)
            device = host.device_session
            assert device is not None
            lock = encode_command(CommandPacket(10**6 + i, True, True, sample.seq), KEY,
                                  host.session, device)
            intruder.sendto(lock, ("127.0.0.1", server.port))  # right key, wrong address
            forged = encode_command(CommandPacket(10**6 + i, True, True, sample.seq),
                                    bytes(32), host.session, device)
            host._sendto(forged)  # from the host's own address, without the key
            old = bytearray(lock[:-32])
            old[2] = 2
            host._sendto(bytes(old) + tag(KEY, bytes(old)))  # authentic, another version
    assert all(st & Status.WATCHDOG_RELEASED for st in statuses)
    assert not any(st & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT) for st in statuses)
    # The device reports its drops in its samples: wait until the last forged one shows.
    # On a busy machine a stalled device reads a burst at once, and past its budget of 8
    # datagrams a period it counts them as `flood` (statistics only), so the wait ends
    # at the deadline then, and the counts are checked with the budget's share.
    deadline = time.monotonic() + 5.0
    while host.link_counters()["device_auth"] < 20 and time.monotonic() < deadline:
        _read(host)
    reported = host.link_counters()["device_auth"]
    stats = server.finish()
    flood = stats.drops.get("flood", 0)
    assert stats.drops["foreign"] == 20
    auth, version = stats.malformed["auth"], stats.summary()["unknown_version"]
    assert auth <= 20 and version <= 20 and auth + version + flood == 40, stats.summary()
    assert reported == auth == stats.summary()["auth_failures"]
    assert stats.commands == 0 and stats.host_changes == 0
    # Answered with VERSION at most once per second; the host reads it (3..3: no problem).
    assert 1 <= stats.versions_sent <= 2 and host.stats.versions == stats.versions_sent
    assert host.problem == ""


def _join(sock: socket.socket, port: int, session: int, hello_seq: int) -> tuple[int, bytes]:
    """HELLO (again, while the device rate-limits its answers) and JOIN from a raw
    socket; returns the device session and the JOIN sent."""
    dev = ("127.0.0.1", port)
    seqs = iter(range(hello_seq, hello_seq + 1000))
    answer = wait_for(lambda: _challenge_for(sock, dev, next(seqs), session), 5,
                      "a CHALLENGE")
    assert answer is not None
    packet, sender = answer
    assert packet.firmware == FIRMWARE
    join = encode_join(JoinPacket(packet.hello_seq + 1, packet.challenge), KEY, session,
                       sender)
    sock.sendto(join, dev)
    return sender, join


def _next_sample(sock: socket.socket) -> Sample:
    while not isinstance(packet := decode_frame(sock.recv(2048), KEY).packet, Sample):
        pass
    return packet


def test_the_device_rules_join_sequence_freshness_and_the_host_address(
        server: Running) -> None:
    a, b = _raw_host(), _raw_host()
    b_port = b.getsockname()[1]
    dev = ("127.0.0.1", server.port)
    with a, b:
        d, join_a = _join(a, server.port, 0xA, 100)
        first = decode_frame(a.recv(2048), KEY)
        while not isinstance(first.packet, Sample):  # a CHALLENGE to a repeated HELLO
            first = decode_frame(a.recv(2048), KEY)
        assert first.packet.seq == 0
        assert (first.sender, first.receiver) == (d, 0xA)

        def command(seq: int, echo: int, receiver: int = d, sender: int = 0xA) -> bytes:
            return encode_command(CommandPacket(seq, True, False, echo), KEY, sender, receiver)

        a.sendto(command(102, 0), dev)  # applied
        a.sendto(command(101, 0), dev)  # not later than 102: replay
        a.sendto(command(102, 0), dev)  # a copy: replay
        a.sendto(command(103, 0, receiver=d ^ 1), dev)  # to another boot: replay
        a.sendto(command(104, 999), dev)  # echoes no sample sent: stale_echo
        a.sendto(join_a, dev)  # its challenge is spent: replay
        wait_for(lambda: server.result or (server.model.commands[-1] is not None
                 and server.model.commands[-1].lock_left), 5, "the lock applied")
        hello = bytearray(encode_hello(HelloPacket(7), KEY, 0xA)[:-32])
        hello[-8:] = d.to_bytes(8, "little")  # a HELLO naming a receiver session
        a.sendto(bytes(hello) + tag(KEY, bytes(hello)), dev)
        d_b, _ = _join(b, server.port, 0xB, 1)  # another host joins: the stream moves
        assert d_b == d
        b_sample = _next_sample(b)
        assert b_sample.seq > 0  # same device clock
        assert b_sample.status & Status.WATCHDOG_RELEASED  # a new session inherits no lock
        assert not b_sample.status & Status.SOLENOID_LEFT
        a.sendto(command(105, b_sample.seq), dev)  # not the joined session: replay
        _next_sample(b)
        _next_sample(b)
    stats = server.finish()
    assert stats.commands == 1 and stats.drops["stale_echo"] == 1
    assert stats.drops["replay"] == 5 and stats.malformed["reserved"] == 1
    assert stats.hellos >= 2 and stats.joins == 2 and stats.host_changes == 1
    assert stats.host == f"127.0.0.1:{b_port}"


def _challenge_for(sock: socket.socket, dev: tuple[str, int], seq: int, session: int = 0xA
                   ) -> tuple[ChallengePacket, int] | None:
    """Say HELLO `seq`; the CHALLENGE answering it (and its sender), or None if none
    came within 0.1 s."""
    sock.sendto(encode_hello(HelloPacket(seq), KEY, session), dev)
    deadline = time.monotonic() + 0.1
    while (left := deadline - time.monotonic()) > 0:
        sock.settimeout(left)
        try:
            frame = decode_frame(sock.recv(2048), KEY)
        except TimeoutError:
            break
        if isinstance(frame.packet, ChallengePacket) and frame.packet.hello_seq == seq:
            sock.settimeout(0.5)
            return frame.packet, frame.sender
    sock.settimeout(0.5)
    return None


def test_every_hello_is_answered_challenges_redrawn_and_single_use(server: Running) -> None:
    a = _raw_host()
    dev = ("127.0.0.1", server.port)
    with a:
        a.sendto(encode_hello(HelloPacket(1), KEY, 0xA), dev)
        a.sendto(encode_hello(HelloPacket(2), KEY, 0xA), dev)  # at once: answered too
        first = decode_frame(a.recv(2048), KEY).packet
        second = decode_frame(a.recv(2048), KEY).packet
        assert isinstance(first, ChallengePacket) and first.hello_seq == 1
        assert isinstance(second, ChallengePacket) and second.hello_seq == 2
        assert second.challenge == first.challenge  # one challenge, not redrawn
        seqs = iter(range(3, 1000))
        again = wait_for(lambda: _challenge_for(a, dev, next(seqs)), 5, "a CHALLENGE")
        assert again is not None
        assert again[0].challenge == first.challenge  # not spent, younger than 500 ms
        join = encode_join(JoinPacket(1000, first.challenge), KEY, 0xA, again[1])
        a.sendto(join, dev)
        assert isinstance(_next_sample(a), Sample)
        # Spent: the next HELLO draws a new challenge, and the old JOIN is a replay.
        fresh = wait_for(lambda: _challenge_for(a, dev, next(seqs)), 5, "a new CHALLENGE")
        assert fresh is not None
        assert fresh[0].challenge != first.challenge
        a.sendto(join, dev)
        _next_sample(a)
        _next_sample(a)
    stats = server.finish()
    assert stats.drops["replay"] == 1 and "challenge_limited" not in stats.summary()
    assert stats.joins == 1 and stats.challenges == stats.hellos >= 4


def test_stopped_heartbeat_cuts_the_drivers_in_the_plant(server: Running,
                                                          host: UdpDevice) -> None:
    """The monostable model: with STOP_HEARTBEAT the drivers go off 30 ms after the last
    edge, the mechanism stops getting the lock although the firmware still drives it,
    and the heartbeat resumes with the first command without the flag."""
    for _ in range(5):
        _read(host)
        host.send(LOCK_LEFT)
    stop = LockCommand(seq=0, lock_left=True, lock_right=False, stop_heartbeat=True)
    seen = []
    for _ in range(8):
        sample = _read(host)
        seen.append(sample.status)
        host.send(stop)
    assert seen[0] & Status.SOLENOID_LEFT and not seen[0] & Status.DRIVERS_OFF
    stopped = [i for i, st in enumerate(seen) if st & Status.HEARTBEAT_STOPPED]
    off = [i for i, st in enumerate(seen) if st & Status.DRIVERS_OFF]
    assert stopped and off and off[0] - stopped[0] <= 3  # 30 ms + one period at most
    assert all(seen[i] & Status.SOLENOID_LEFT for i in off)  # the firmware still drives
    applied = server.model.commands
    assert any(c is not None and c.lock_left for c in applied)
    assert applied[-1] is not None and not applied[-1].lock_left  # the plant got no lock
    # The heartbeat resumes with the commands without the flag. A test thread the
    # machine's load holds up reads samples the device made before they arrived, so it
    # reads on (at most 20) until the first one made after.
    host.send(LOCK_LEFT)
    resumed = False
    for _ in range(20):
        sample = _read(host)
        host.send(LOCK_LEFT)
        if not sample.status & (Status.DRIVERS_OFF | Status.HEARTBEAT_STOPPED):
            resumed = True
            break
    assert resumed, "the heartbeat did not resume with commands without the flag"
    assert server.finish().driver_cutoffs == 1


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
