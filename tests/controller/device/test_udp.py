"""UdpDevice against a hand-driven fake device socket on loopback: exact packets in, exact
behaviour out (the join, ordering, wrap, foreign, forged, replayed and malformed
datagrams, challenges and samples of stale sessions, device restarts as new sessions,
versions, commands, release)."""

from __future__ import annotations

import itertools
import socket
import time
from collections.abc import Iterator

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.device import udp
from controller.device.auth import key_id
from controller.device.base import NO_LOCK, DeviceError, LockCommand, Sample, Status
from controller.device.protocol import (
    ChallengePacket,
    CommandPacket,
    HelloPacket,
    JoinPacket,
    Packet,
    VersionPacket,
    decode_frame,
    encode_challenge,
    encode_sample,
    encode_version,
    seq_diff,
)
from controller.device.udp import UdpDevice
from tests.polling import wait_for

KEY = bytes(range(32))
UNIQUE = bytes(range(16))


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
        self.challenge = bytes(range(100, 116))

    def receive(self) -> Packet:
        data, addr = self.sock.recvfrom(2048)
        self.host = (str(addr[0]), int(addr[1]))
        frame = decode_frame(data, KEY)
        self.host_session, self.last_receiver = frame.sender, frame.receiver
        return frame.packet

    def receive_not_hello(self) -> Packet:
        """The next packet that is not a HELLO (the host repeats those while joining)."""
        while isinstance(packet := self.receive(), HelloPacket):
            pass
        return packet

    def challenge_bytes(self, hello_seq: int, receiver: int | None = None) -> bytes:
        answer = ChallengePacket(hello_seq, self.challenge, UNIQUE, "fake 3")
        return encode_challenge(answer, KEY, self.session,
                                self.host_session if receiver is None else receiver)

    def sample_bytes(self, seq: int, status: Status = Status.NONE, key: bytes = KEY) -> bytes:
        sample = Sample(seq=seq, t=seq * 0.01, counts=(seq % 16384, 1, 2, 3), status=status)
        return encode_sample(sample, key, self.session, self.host_session)

    def send_sample(self, seq: int, status: Status = Status.NONE) -> None:
        assert self.host is not None
        self.sock.sendto(self.sample_bytes(seq, status), self.host)

    def send_raw(self, data: bytes) -> None:
        assert self.host is not None
        self.sock.sendto(data, self.host)

    def join(self, dev: UdpDevice) -> JoinPacket:
        """Answer the host's latest HELLO with a CHALLENGE (the host reading until it
        says HELLO); return its JOIN."""
        hellos: list[Packet] = []

        def said_hello() -> bool:
            self.sock.settimeout(0.0)
            try:
                while True:
                    hellos.append(self.receive())
            except BlockingIOError:
                pass
            finally:
                self.sock.settimeout(1.0)
            if not hellos:
                dev.read(0.01)
            return bool(hellos)

        wait_for(said_hello, 5, "a HELLO from the host")
        hello = hellos[-1]
        assert isinstance(hello, HelloPacket)
        self.send_raw(self.challenge_bytes(hello.host_seq))
        dev.read(0.02)
        join = self.receive_not_hello()
        assert isinstance(join, JoinPacket)
        return join


@pytest.fixture
def link() -> Iterator[tuple[UdpDevice, FakeDevice]]:
    fake = FakeDevice()
    dev = UdpDevice(device_host="127.0.0.1", device_port=fake.port, key=KEY)
    dev.open()
    fake.join(dev)
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
    fake.send_sample(0)  # not joined to this boot yet: dropped
    assert dev.read(0.05) is None and dev.stats.replayed == 1
    join = fake.join(dev)  # the host joins again after 250 ms without a sample
    assert fake.last_receiver == 0xB007 and fake.host_session == dev.session
    assert join.challenge == fake.challenge
    for seq in range(3):
        fake.send_sample(seq)
    assert _seqs(dev, 3) == [5001, 5002, 5003]
    assert dev.stats.restarts == 1
    assert any("restarted" in f for f in dev.faults())
    fake.send_raw(old)  # authentic, but from the session the device left behind
    fake.send_raw(fake.sample_bytes(2))  # and the last one again
    assert dev.read(0.05) is None
    assert (dev.stats.replayed, dev.stats.duplicates) == (2, 1)
    assert dev.link_counters()["replay"] == 3


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
    assert fake.last_receiver == fake.session  # the JOIN names the device's session
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


def test_hello_every_100_ms_until_a_challenge_arrives() -> None:
    fake = FakeDevice()
    with UdpDevice(device_port=fake.port, key=KEY) as dev:
        assert dev.read(0.35) is None
        hellos = [fake.receive() for _ in range(dev.stats.hellos_sent)]
        assert all(isinstance(h, HelloPacket) for h in hellos)
        assert 3 <= len(hellos) <= 5 and fake.last_receiver == 0
        seqs = [h.host_seq for h in hellos if isinstance(h, HelloPacket)]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # +1 per packet
        assert dev.identity is None and dev.problem == ""
    fake.sock.close()


def test_join_answers_the_challenge_and_identity_follows_the_first_sample(
        link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    assert dev.stats.joins == 1 and dev.identity is None
    fake.send_sample(0)
    _seqs(dev, 1)
    assert dev.identity is not None
    assert (dev.identity.unique_id, dev.identity.firmware) == (UNIQUE.hex(), "fake 3")
    assert (dev.identity.key_id, dev.identity.device_session) == (key_id(KEY), fake.session)
    assert dev.joined


def test_challenges_that_answer_no_recent_hello_of_this_session_are_replays(
        monkeypatch: pytest.MonkeyPatch) -> None:
    fake = FakeDevice()
    monkeypatch.setattr(udp, "HELLO_MEMORY_S", 0.15)
    with UdpDevice(device_port=fake.port, key=KEY) as dev:
        first = fake.receive()
        assert isinstance(first, HelloPacket)
        old_session = fake.host_session
        # To an earlier session of this host (recorded before it restarted).
        fake.send_raw(fake.challenge_bytes(first.host_seq, receiver=old_session ^ 1))
        # Answering a HELLO this host never sent.
        fake.send_raw(fake.challenge_bytes(first.host_seq + 1000))
        assert dev.read(0.1) is None
        assert dev.stats.replayed == 2 and dev.stats.joins == 0
        # Answering one of its own HELLOs older than the host's memory (the host read
        # late, or the path delayed it): late, not a replay (the link step would fail
        # on a replay), and no JOIN.
        wait_for(lambda: dev.read(0.01) is None and dev.stats.hellos_sent >= 3, 5,
                 "two more HELLOs")
        fake.send_raw(fake.challenge_bytes(first.host_seq))
        dev.read(0.02)
        assert (dev.stats.replayed, dev.stats.late_challenges, dev.stats.joins) == (2, 1, 0)
        # A good one: one JOIN; the same CHALLENGE again (a copy) changes nothing.
        latest = dev._host_seq
        fake.send_raw(fake.challenge_bytes(latest))
        fake.send_raw(fake.challenge_bytes(latest))
        dev.read(0.02)
        assert dev.stats.joins == 1 and dev.stats.replayed == 2
        assert dev.stats.late_challenges == 2
    fake.sock.close()


def test_a_challenge_to_a_hello_that_crossed_the_join_makes_no_second_join() -> None:
    """Two HELLOs out, the device answers both with the same challenge: the JOIN to the
    first answers both; a JOIN to the second would spend nothing (the device drops it
    as a replay of the spent challenge), so none is sent."""
    fake = FakeDevice()
    with UdpDevice(device_port=fake.port, key=KEY) as dev:
        first = fake.receive()
        assert isinstance(first, HelloPacket)
        wait_for(lambda: dev.read(0.01) is None and dev.stats.hellos_sent >= 2, 5,
                 "a second HELLO")
        second = dev._host_seq
        assert second != first.host_seq
        fake.send_raw(fake.challenge_bytes(first.host_seq))
        dev.read(0.02)
        fake.send_raw(fake.challenge_bytes(second))
        dev.read(0.02)
        assert (dev.stats.joins, dev.stats.late_challenges, dev.stats.replayed) == (1, 1, 0)
    fake.sock.close()
    fake.sock.close()


def test_a_host_busy_after_its_hello_answers_only_the_challenge_drawn_since() -> None:
    """The worker says HELLO at open() and then warms its controller for most of a
    second. Its next HELLO comes after the device's redraw age, so the device answers it
    with a new challenge: the JOIN carries that one, and the CHALLENGE to the first HELLO
    (queued meanwhile, its challenge dead) is set aside as late, not answered."""
    fake = FakeDevice()
    with UdpDevice(device_port=fake.port, key=KEY) as dev:
        first = fake.receive()
        assert isinstance(first, HelloPacket)
        fake.send_raw(fake.challenge_bytes(first.host_seq))  # queued: the host is busy
        time.sleep(udp.HELLO_REDRAW_GAP_S + 0.05)
        dev.read(0.0)  # says its second HELLO first, then reads the stale CHALLENGE
        second = fake.receive()
        assert isinstance(second, HelloPacket) and second.host_seq != first.host_seq
        assert (dev.stats.joins, dev.stats.late_challenges, dev.stats.replayed) == (0, 1, 0)
        fake.challenge = bytes(range(200, 216))  # the device redrew for the second HELLO
        fake.send_raw(fake.challenge_bytes(second.host_seq))
        dev.read(0.02)
        join = fake.receive_not_hello()
        assert isinstance(join, JoinPacket) and join.challenge == bytes(range(200, 216))
        assert dev.stats.joins == 1
    fake.sock.close()


def test_samples_of_a_stale_session_are_replays(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_sample(1)
    _seqs(dev, 1)
    device, host = fake.session, fake.host_session
    fake.session = device ^ 1  # an earlier boot of the device (never joined)
    fake.send_sample(2)
    fake.session, fake.host_session = device, host ^ 1  # to an earlier host session
    fake.send_sample(3)
    fake.host_session = host
    fake.send_sample(4)
    assert _seqs(dev, 1) == [4]
    assert dev.stats.replayed == 2 and dev.stats.gaps == 1


def test_rejoin_after_250_ms_without_a_sample_keeps_the_host_session(
        link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_sample(1)
    _seqs(dev, 1)
    session = dev.session
    t0 = time.monotonic()
    join = fake.join(dev)
    assert time.monotonic() - t0 >= 0.2  # no HELLO while the session worked
    assert fake.host_session == session and join.host_seq > 0
    assert dev.stats.joins == 2 and dev.stats.restarts == 0
    fake.send_sample(2)
    assert _seqs(dev, 1) == [2]  # the same device session goes on


def test_a_version_answer_is_reported_and_a_silent_device_is_named(
        monkeypatch: pytest.MonkeyPatch) -> None:
    fake = FakeDevice()
    monkeypatch.setattr(udp, "HELLO_INTERVAL_S", 0.002)
    with UdpDevice(device_port=fake.port, key=KEY) as dev:
        wait_for(lambda: dev.read(0.01) is None and dev.stats.hellos_sent >= 20, 10,
                 "20 HELLOs")
        assert "no version 3 device answers at 127.0.0.1" in dev.problem
        assert "older than protocol version 3" in dev.problem and key_id(KEY) in dev.problem
        assert dev.problem in dev.faults() and dev.problem in dev.faults()  # standing
        fake.receive()
        fake.send_raw(encode_version(VersionPacket(1, 2), KEY))
        dev.read(0.02)
        assert dev.problem.startswith("the device speaks protocol versions 1..2; this host "
                                      "speaks 3..3")
        assert dev.link_counters()["version"] == 1
        forged = bytearray(encode_version(VersionPacket(4, 4), KEY))
        forged[-1] ^= 1
        fake.send_raw(bytes(forged))
        dev.read(0.02)
        assert "1..2" in dev.problem and dev.stats.malformed["auth"] == 1
        dev.send(NO_LOCK)
        assert dev.stats.commands_sent == 0  # nothing to answer: nothing runs
    fake.sock.close()


def test_stop_heartbeat_travels_in_the_command_flag(link: tuple[UdpDevice, FakeDevice]) -> None:
    dev, fake = link
    fake.send_sample(7)
    _seqs(dev, 1)
    dev.send(LockCommand(seq=0, lock_left=True, lock_right=False, stop_heartbeat=True))
    packet = fake.receive()
    assert isinstance(packet, CommandPacket)
    assert (packet.stop_heartbeat, packet.lock_left, packet.echo_seq) == (True, True, 7)


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
    dev.device_session = 7  # as if joined
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
