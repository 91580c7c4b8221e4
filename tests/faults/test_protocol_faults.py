"""Attacks on the device link, on the real processes (device-sim over UDP, the worker):
forged SAMPLE packets, forged COMMAND packets from another local process, recorded
samples and commands sent again (the attacks of protocol version 3's threat model are
in test_link_attacks.py). Before protocol version 2 every one of them got through
(1,500 forged samples became 304 locked ticks; forged commands energised both
solenoids on every sample; a sample repeated 25 times was taken as a device restart)."""

from __future__ import annotations

import math
import secrets
import socket
import struct
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from controller.controllers.spec import ControllerSpec
from controller.device.auth import TAG_BYTES, create_key
from controller.device.base import Sample
from controller.device.protocol import SAMPLE_BODY, SESSIONS, CommandPacket, encode_command
from controller.device.protocol import encode_sample as encode
from controller.lowlevel.encoders import DEFAULT_LAYOUT
from controller.tick_record import TickRecord
from tests.faults.device_rig import (
    Proxy,
    Worker,
    device_process,
    locked_ticks,
    stop_and_read_stats,
)
from tests.polling import free_udp_port, wait_for

pytestmark = pytest.mark.slow

HEADER = 8


@pytest.fixture
def key_file(tmp_path: Path) -> Iterator[Path]:
    path = tmp_path / "device.key"
    create_key(path)
    yield path


def _sessions(packet: bytes) -> tuple[int, int]:
    """Sender and receiver sessions of a packet: readable by anyone on the network."""
    s, r = SESSIONS.unpack_from(packet, len(packet) - TAG_BYTES - SESSIONS.size)
    return int(s), int(r)


def _max_deflection_deg(records: list[TickRecord]) -> float:
    """Largest spring deflection: an engaged ratchet deflects the spring by tens of
    degrees in a step or a squat; unlocked, only the encoders' error shows (< 2 deg)."""
    return math.degrees(max(max(r.alpha_left, r.alpha_right) for r in records))


def _seq(sample_packet: bytes) -> int:
    return int(struct.unpack_from("<I", sample_packet, HEADER + 8)[0])


def test_forged_and_replayed_samples_and_forged_commands_change_nothing(
        key_file: Path, device_implementation: str) -> None:
    port = free_udp_port()
    with device_process(port, key_file, "walking",
                        implementation=device_implementation) as dev, \
            Proxy(port) as proxy, \
            Worker(proxy.port, key_file, "pec") as worker:
        walking = worker.wait_ticks(200)
        assert locked_ticks(walking) == 0  # the PEC does not lock a walking wearer
        # The link's own start may already have counted a replay at the device: once,
        # at load 9, the count was 1 with no attack packet able to cause it (a genuine
        # packet of the start sent again, not yet traced). The attack must add none.
        replays_before = worker.link_drops().get("device_replay", 0)

        # 1. 1,500 forged SAMPLEs: a deep squat at 100 Hz, numbered just ahead of the
        # device, with the sessions copied from its packets; the attacker has no key.
        genuine = proxy.to_worker[-1]
        device_session, host_session = _sessions(genuine)
        next_seq = _seq(genuine) + 5
        wrong_key = secrets.token_bytes(32)
        t0 = time.monotonic()
        for i in range(1500):
            q = min(2.0, 0.02 * i % 2.0)  # flexing at 2 rad/s, over and over
            counts = DEFAULT_LAYOUT.encode(q, q, q, q)
            forged = Sample(seq=next_seq + i, t=0.0, counts=counts)
            proxy.send_to_worker(encode(forged, wrong_key, device_session, host_session))
            if i % 10 == 9:
                time.sleep(0.005)

        # 2. One genuine sample recorded earlier, sent again 30 times (stale, repeated).
        recorded = proxy.to_worker[len(proxy.to_worker) // 2]
        for _ in range(30):
            proxy.send_to_worker(recorded)
            time.sleep(0.002)

        # 3. Another local process sends well-formed lock-both COMMANDs to the device,
        # 301 of them at 100 Hz, addressed to the device's session (read off the wire).
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as attacker:
            for i in range(301):
                lock = CommandPacket(host_seq=10**6 + i, lock_left=True, lock_right=True,
                                     echo_seq=_seq(genuine) + i)
                attacker.sendto(encode_command(lock, wrong_key, 0xBAD, device_session),
                                ("127.0.0.1", port))
                time.sleep(0.01)
        attack_s = time.monotonic() - t0

        wait_for(lambda: worker.link_drops().get("auth") == 1500, 30,
                 "the worker to count 1,500 forged samples")
        # The device reports its tag failures in every sample; on a busy machine part of
        # a burst can instead meet its per-period authentication budget (`flood`, in its
        # statistics line only). Wait until the count settles.
        settled = SettledCount(lambda: worker.link_drops().get("device_auth", 0))
        wait_for(lambda: settled.reached(301), 30, "the device to report 301 forged commands")
        after = worker.wait_ticks(100)
        drops = worker.link_drops()
        ticks = worker.ticks()
        stats = stop_and_read_stats(dev)

    flood = stats["drops"].get("flood", 0)
    assert drops["auth"] == 1500
    assert drops["device_auth"] <= 301 <= drops["device_auth"] + flood, stats
    # A recorded sample of the live session is older than the ones used: stale (a
    # duplicate if it was the latest), never a new session.
    assert drops["replay"] + drops["stale"] == 30 and drops["device_restarts"] == 0
    assert drops["device_replay"] == replays_before
    # Nothing forged or replayed reached a controller: no lock, no mechanism engaged,
    # the device stream continued in order (the worker never jumped to forged numbers).
    assert locked_ticks(ticks) == 0
    assert _max_deflection_deg(ticks) < 3.0  # no ratchet engaged (encoder error only)
    seqs = [r.seq for r in ticks]
    assert all(b > a for a, b in zip(seqs, seqs[1:], strict=False))
    # Every tick is the device's own sample n at time n * 10 ms (forged ones said t = 0).
    assert all(abs(r.t - 0.01 * r.seq) < 1e-6 for r in ticks)
    assert len(after) == 100 and attack_s > 3.0
    print(f"forged/replayed: {len(ticks)} ticks, link drops {drops}, "
          f"{locked_ticks(ticks)} locked ticks")


def test_recorded_lock_commands_sent_again_are_dropped(key_file: Path,
                                                        device_implementation: str) -> None:
    port = free_udp_port()
    with device_process(port, key_file, "squat-sequence",
                        implementation=device_implementation) as dev, Proxy(port) as proxy, \
            Worker(proxy.port, key_file, "pec") as worker:
        wait_for(lambda: locked_ticks(worker.ticks()) > 20, 90, "the PEC to lock a squat")
        # The attacker keeps every COMMAND that asked for both locks (bits readable).
        locks = [d for d in proxy.to_device if d[3] == 2 and d[HEADER + 8] == 3]
        assert locks
        worker.sup.set_controller(ControllerSpec("none"))
        wait_for(lambda: worker.runs[-1].controller == "none", 30, "the switch to none")
        # Wait for the held lock to end and the mechanism to let go (the wearer stands).
        def free_for_a_second() -> bool:
            recent = worker.ticks()[-100:]
            return len(recent) == 100 and locked_ticks(recent) == 0 \
                and _max_deflection_deg(recent) < 3.0
        wait_for(free_for_a_second, 60, "the mechanism to let go")
        start = len(worker.ticks())
        sent = 0

        def squatted() -> bool:  # the wearer flexed 30 deg since the replays began
            return any(r.q_raw_left > 0.5 and r.truth_activity == "squat"
                       for r in worker.ticks()[start:])

        deadline = time.monotonic() + 30
        # Replay the recorded lock-both commands at 100 Hz, in a loop, until the wearer
        # has squatted under them (something a lock would act on).
        while not (squatted() and sent >= 300) and time.monotonic() < deadline:
            proxy.send_to_device(locks[sent % len(locks)])
            sent += 1
            time.sleep(0.01)
        # The device reports its replay drops in every sample; on a busy machine a burst
        # of replays can also meet the per-period authentication budget (counted as
        # `flood` in its statistics line, not in samples). Wait until the count settles.
        settled = SettledCount(lambda: worker.link_drops().get("device_replay", 0))
        wait_for(lambda: settled.reached(sent), 30, f"the device to report the {sent} replays")
        worker.wait_ticks(200)
        replayed_during = worker.ticks()[start:]
        drops = worker.link_drops()
        stats = stop_and_read_stats(dev)

    # Every replay dropped and counted, as a replay or (in a burst) by the budget, and no
    # datagram of the worker's own counted as a replay. (A JOIN for a CHALLENGE that
    # answered a second HELLO crossing the first CHALLENGE used to be refused as a replay
    # of the spent challenge; the host now answers one CHALLENGE per join,
    # `UdpDevice._on_challenge`.)
    flood = stats["drops"].get("flood", 0)
    assert drops["device_replay"] <= sent <= drops["device_replay"] + flood, (sent, stats)
    assert drops["device_auth"] == 0
    assert locked_ticks(replayed_during) == 0
    assert _max_deflection_deg(replayed_during[100:]) < 3.0
    # The wearer squatted while the replays went on: they had something to lock.
    assert any(r.q_raw_left > 0.5 and r.truth_activity == "squat" for r in replayed_during)
    assert sent >= 300
    print(f"replayed commands: {sent} sent, device dropped {drops['device_replay']} as "
          f"replays and {flood} by its budget, "
          f"{locked_ticks(replayed_during)} locked ticks in {len(replayed_during)}")


class SettledCount:
    """A counter that has reached a target, or stopped rising for a second (read by
    `wait_for` every few ms)."""

    def __init__(self, read: Callable[[], int]) -> None:
        self.read = read
        self.value = read()
        self.since = time.monotonic()

    def reached(self, target: int) -> bool:
        value = self.read()
        if value != self.value:
            self.value, self.since = value, time.monotonic()
        return value >= target or time.monotonic() - self.since > 1.0


def test_sample_fields_offsets_match_the_protocol() -> None:
    """The attacker's view above reads fields at their documented offsets."""
    s = Sample(seq=77, t=0.5, counts=(1, 2, 3, 4))
    data = encode(s, bytes(32), 5, 6)
    assert _seq(data) == 77 and _sessions(data) == (5, 6)
    assert len(data) == HEADER + SAMPLE_BODY.size + SESSIONS.size + TAG_BYTES
