"""UdpDevice against a hand-driven fake device socket on loopback: exact packets in, exact
behaviour out (ordering, wrap, foreign, forged, replayed and malformed datagrams, device
restarts as new sessions, commands, release)."""

from __future__ import annotations

import itertools
import socket
import time
from collections.abc import Iterator

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.device.base import NO_LOCK, DeviceError, LockCommand, Sample, Status
from controller.device.protocol import (
    CommandPacket,
    HelloPacket,
    decode_frame,
    encode_sample,
    seq_diff,
)
from controller.device.udp import UdpDevice

KEY = bytes(range(32))


class FakeDevice:
    """A bare socket playing the exoskeleton, so each test controls every datagram."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(1.0)
        self.port = int(self.sock.getsockname()[1])
        self.host: tuple[str, int] | None = None
        self.session = 0x5EED
        self.host_session = 0
        self.last_receiver = -1

    def receive(self) -> CommandPacket | HelloPacket:
        data, addr = self.sock.recvfrom(2048)
        self.host = (str(addr[0]), int(addr[1]))
        frame = decode_frame(data, KEY)
        self.host_session, self.last_receiver = frame.sender, frame.receiver
        assert isinstance(frame.packet, CommandPacket | HelloPacket)
        return frame.packet

    def sample_bytes(self, seq: int, status: Status = Status.NONE, key: bytes = KEY) -> bytes:
        sample = Sample(seq=seq, t=seq * 0.01, counts=(seq % 16384, 1, 2, 3), status=status)
        return encode_sample(sample, key, self.session, self.host_session)

    def send_sample(self, seq: int, status: Status = Status.NONE) -> None:
        assert self.host is not None
        self.sock.sendto(self.sample_bytes(seq, status), self.host)

    def send_raw(self, data: bytes) -> None:
        assert self.host is not None
        self.sock.sendto(data, self.host)


@pytest.fixture
def link() -> Iterator[tuple[UdpDevice, FakeDevice]]:
    fake = FakeDevice()
    dev = UdpDevice(device_host="127.0.0.1", device_port=fake.port, key=KEY)
    dev.open()
    hello = fake.receive()
    assert isinstance(hello, HelloPacket)
    yield dev, fake
    dev.close()
    fake.sock.close()


def _seqs(dev: UdpDevice, n: int) -> list[int]:
    out = []
    for _ in range(n):
        s = dev.read(0.5)
        assert s is not None
        out.append(s.seq)
    return out


def test_open_says_hello_from_its_own_address(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    assert dev.kind == "udp"
    assert fake.host == dev.address


def test_samples_in_order_and_decoded(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_sample(10, Status.LOCKED_RIGHT)
    fake.send_sample(11)
    s = dev.read(0.5)
    assert s is not None
    assert (s.seq, s.t, s.counts, s.status) == (10, 0.1, (10, 1, 2, 3), Status.LOCKED_RIGHT)
    assert _seqs(dev, 1) == [11]
    assert dev.read(0.02) is None
    assert dev.faults() == []


def test_duplicates_and_out_of_order_are_dropped(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    for seq in (1, 3, 3, 2, 4):  # 3 again: seen; 2: new, but 3 was already used
        fake.send_sample(seq)
    assert _seqs(dev, 3) == [1, 3, 4]
    assert (dev.stats.duplicates, dev.stats.stale) == (1, 1)
    faults = dev.faults()
    assert "1 duplicate sample(s) dropped" in faults
    assert "1 out-of-order sample(s) dropped" in faults
    assert dev.faults() == []  # reported once


def test_gaps_are_counted_and_visible_in_seq(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    for seq in (1, 2, 6, 7, 9):
        fake.send_sample(seq)
    assert _seqs(dev, 5) == [1, 2, 6, 7, 9]
    assert (dev.stats.gaps, dev.stats.missing) == (2, 4)
    assert "2 sequence gap(s), 4 sample(s) missing" in dev.faults()


def test_wrap_keeps_host_sequence_increasing(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    for seq in (2**32 - 2, 2**32 - 1, 0, 1):
        fake.send_sample(seq)
    assert _seqs(dev, 4) == [2**32 - 2, 2**32 - 1, 2**32, 2**32 + 1]
    assert dev.stats.gaps == 0


def test_device_restart_is_a_new_session_and_old_sessions_stay_dead(
    link: tuple[UdpDevice, FakeDevice],
) -> None:
    dev, fake = link
    fake.send_sample(5000)
    old = fake.sample_bytes(5001)
    assert _seqs(dev, 1) == [5000]
    fake.session = 0xB007  # the device rebooted: a new session, counting from 0
    for seq in range(3):
        fake.send_sample(seq)
    assert _seqs(dev, 3) == [5001, 5002, 5003]
    assert dev.stats.restarts == 1
    assert any("restarted" in f for f in dev.faults())
    fake.send_raw(old)  # authentic, but from the session the device left behind
    fake.send_raw(fake.sample_bytes(1))  # and one already seen
    assert dev.read(0.05) is None
    assert (dev.stats.replayed, dev.stats.duplicates) == (1, 1)
    assert dev.link_counters()["replay"] == 2


def test_forged_and_misaddressed_samples_are_dropped(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_raw(fake.sample_bytes(1, key=bytes(32)))  # the wrong key
    host = fake.host_session
    fake.host_session = host ^ 1  # to another session of the host (an earlier one)
    fake.send_sample(2)
    fake.host_session = host
    fake.send_sample(3)
    assert _seqs(dev, 1) == [3]
    assert dev.stats.malformed["auth"] == 1
    assert dev.stats.replayed == 1
    assert dev.link_counters()["auth"] == 1


def test_commands_name_the_device_session_once_known(
    link: tuple[UdpDevice, FakeDevice],
) -> None:
    dev, fake = link
    assert fake.last_receiver == 0  # the HELLO: device unknown
    fake.send_sample(1)
    _seqs(dev, 1)
    dev.send(NO_LOCK)
    fake.receive()
    assert (fake.host_session, fake.last_receiver) == (dev.session, fake.session)


def test_malformed_packets_are_counted_by_reason(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    good = bytearray(fake.sample_bytes(1))
    bad_tag = bytes(good[:-1]) + bytes([good[-1] ^ 0xFF])
    fake.send_raw(b"EX")
    fake.send_raw(bad_tag)
    fake.send_raw(b"ZZ" + bytes(good[2:]))
    fake.send_sample(1)
    assert _seqs(dev, 1) == [1]
    assert dict(dev.stats.malformed) == {"short": 1, "auth": 1, "magic": 1}
    assert "3 malformed packet(s) dropped (auth: 1, magic: 1, short: 1)" in dev.faults()


def test_foreign_senders_are_ignored(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    packet = fake.sample_bytes(1, Status.LOCKED_LEFT)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other_ip:
        other_ip.bind(("127.0.0.2", 0))  # another loopback address
        other_ip.sendto(packet, dev.address)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other_port:
        other_port.bind(("127.0.0.1", 0))  # the device's IP, but not its port
        other_port.sendto(packet, dev.address)
    assert dev.read(0.1) is None
    assert dev.stats.foreign == 2
    assert dev.stats.samples == 0
    assert "2 packet(s) from foreign addresses ignored" in dev.faults()


def test_commands_echo_the_last_sample(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_sample(40)
    _seqs(dev, 1)
    dev.send(LockCommand(seq=0, lock_left=True, lock_right=False))
    first = fake.receive()
    assert isinstance(first, CommandPacket)
    assert first.echo_seq == 40
    fake.send_sample(41)
    fake.send_sample(42)
    _seqs(dev, 2)
    dev.send(LockCommand(seq=1, lock_left=False, lock_right=True))
    second = fake.receive()
    assert isinstance(second, CommandPacket)
    assert (second.lock_left, second.lock_right, second.echo_seq) == (False, True, 42)
    assert second.host_seq == first.host_seq + 1
    assert dev.stats.commands_sent == 2


def test_no_command_before_the_device_session_is_known(
    link: tuple[UdpDevice, FakeDevice],
) -> None:
    """A COMMAND before the first sample could only name session 0, which the device
    drops as stale (two such drops, from the worker's first release, once failed a
    fault test); the device starts unlocked, so nothing is sent and the skip counted."""
    dev, fake = link
    dev.release()
    dev.send(LockCommand(seq=0, lock_left=True, lock_right=True))
    assert (dev.stats.commands_sent, dev.stats.commands_unaddressed) == (0, 3)
    fake.sock.settimeout(0.1)
    with pytest.raises(TimeoutError):
        fake.receive()


def test_send_does_not_block(link: tuple[UdpDevice, FakeDevice]) -> None:
    # Far more than the fake reads: every send returns, sent or dropped by the kernel
    # and counted, never waiting. How long they take: bench/bench_device_calls.py.
    dev, fake = link
    fake.send_sample(1)
    _seqs(dev, 1)
    errors = dev.stats.send_errors
    for _ in range(2000):
        dev.send(NO_LOCK)
    assert dev.stats.commands_sent + (dev.stats.send_errors - errors) == 2000
    assert dev._sock is not None and not dev._sock.getblocking()


def test_release_sends_unlock_and_never_raises(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_sample(1)
    _seqs(dev, 1)
    dev.release()
    packet = fake.receive()
    assert isinstance(packet, CommandPacket)
    assert (packet.lock_left, packet.lock_right) == (False, False)
    dev.close()
    dev.release()  # closed: still no exception
    dev.close()
    with pytest.raises(DeviceError):
        dev.read(0.01)


def test_outage_is_reported_when_it_starts_and_ends(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_sample(1)
    _seqs(dev, 1)
    assert dev.read(0.08) is None
    assert dev.faults() == ["link outage: no sample for more than 50 ms"]
    fake.send_sample(2)
    _seqs(dev, 1)
    (ended,) = dev.faults()
    assert ended.startswith("link outage ended: samples resumed after")
    assert dev.stats.outages == 1


def test_read_timeout_is_respected(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, _ = link
    # It waits the timeout out (a read that returned early would spin the loop); how
    # little it overshoots is bench/bench_device_calls.py's.
    t0 = time.monotonic()
    assert dev.read(0.05) is None
    assert time.monotonic() - t0 >= 0.045
    assert dev.read(0.0) is None


def test_hello_repeats_while_no_command_is_sent(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    dev.read(0.6)
    assert isinstance(fake.receive(), HelloPacket)
    assert dev.stats.hellos_sent == 2


def test_unopened_device_refuses() -> None:
    dev = UdpDevice(device_port=9, key=KEY)
    with pytest.raises(DeviceError):
        dev.send(NO_LOCK)
    dev.release()  # never raises, even unopened


@settings(max_examples=200)
@given(
    st.integers(0, 2**32 - 1),
    st.lists(st.integers(-40, 40), min_size=1, max_size=80),
)
def test_host_sequence_never_goes_backwards(start: int, steps: list[int]) -> None:
    """Any mix of jumps, repeats and reordering, across the wrap: the worker only ever
    sees increasing sequence numbers, spaced exactly as the wire's serial distance."""
    dev = UdpDevice(device_host="127.0.0.1", device_port=9, key=KEY)  # never opened
    wire = start
    seen: list[tuple[int, int]] = []
    for step in [0, *steps]:
        wire = (wire + step) % 2**32
        packet = encode_sample(Sample(seq=wire, t=0.0, counts=(0, 0, 0, 0)), KEY, 7,
                               dev.session)
        out = dev._accept(packet, ("127.0.0.1", 9))
        if out is not None:
            seen.append((out.seq, wire))
    assert seen[0] == (start, start)
    for (h0, w0), (h1, w1) in itertools.pairwise(seen):
        assert h1 > h0
        if dev.stats.restarts == 0:
            assert h1 - h0 == seq_diff(w1, w0)
    counted = dev.stats.duplicates + dev.stats.stale + dev.stats.samples
    assert counted == len(steps) + 1
