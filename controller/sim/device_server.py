"""The simulated exoskeleton as a network device: the device side of `docs/device-protocol.md`.

It behaves like the firmware would, so the host cannot tell the difference: samples at
100 Hz on an absolute schedule, datagrams only from the configured host IP and at most
8 tag checks per sample period, a host session only through a JOIN that answers the
device's current single-use challenge, commands only of that session, with a later
sequence number and answering a sample sent less than 100 ms earlier, the watchdog
that drops the solenoids 100 ms after the time of the sample the last applied command
echoed (its `t` on the device clock, at or just before it was sent; not 100 ms after the
command arrived: a command held back on the path gets a shorter life, never a longer
one), and a count of every packet sent late or dropped.
It also models the board's hardware release: the firmware toggles a heartbeat output
once per period, an external monostable keeps the solenoid drivers enabled for 30 ms
after each edge, and the simulated mechanism is energised only where the firmware
drives a solenoid and the drivers are enabled. The simulated wearer starts moving at
the first JOIN, so a given seed gives the host the same data every run.
"""

from __future__ import annotations

import argparse
import copy
import hmac
import json
import math
import os
import secrets
import select
import signal
import socket
import sys
import threading
import time
from collections import Counter, deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any, Protocol

from controller.device.auth import load_key, new_session, parse_unique_id, simulated_unique_id
from controller.device.base import LockCommand, Sample, Status
from controller.device.protocol import (
    CHALLENGE_BYTES,
    CHALLENGE_LIFETIME_MS,
    CHALLENGE_REDRAW_MS,
    DEFAULT_PORT,
    LOWEST_VERSION,
    MAX_PACKET,
    SEQ_MODULUS,
    VERSION,
    WATCHDOG_S,
    ChallengePacket,
    CommandPacket,
    HelloPacket,
    JoinPacket,
    ProtocolError,
    VersionPacket,
    decode_frame,
    encode_challenge,
    encode_sample,
    encode_version,
    seq_diff,
)
from controller.stop_flag import SignalSafeFlag

FRESH_S = 0.100  # a command must answer a sample sent at most this long ago
LATE_S = 0.002  # a sample sent more than this after its due time counts as late
RESYNC_S = 0.25  # further behind than this (process stalled): rebase the schedule, no burst
SENT_RING = 16  # send times of the last samples, for freshness and round trips
AUTH_BUDGET = 8  # datagrams from the host IP handled per sample period; the rest: flood
CHALLENGE_REDRAW_S = CHALLENGE_REDRAW_MS / 1000
CHALLENGE_LIFETIME_S = CHALLENGE_LIFETIME_MS / 1000
VERSION_GAP_S = 1.0  # at most one VERSION reply per this long
HEARTBEAT_HOLD_S = 0.030  # the drivers' monostable holds the enable this long per edge
DRAIN_MAX = 64  # datagrams read per wake-up at most, so a flood cannot starve the sample
KEEP = 360_000  # lateness and round-trip values kept for percentiles: the last hour
SOLENOIDS = Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT
#: The firmware string the Python simulator reports in its CHALLENGE.
FIRMWARE = "exostudy-sim 3"


class ExoskeletonModel(Protocol):
    """What the server needs from a simulated exoskeleton (`SimulatedExoskeleton`)."""

    dt: float

    @property
    def finished(self) -> bool:
        """The script has ended (never true when looping)."""
        ...

    def tick(self, command: LockCommand | None) -> Sample:
        """Advance one period with the solenoid command as the mechanism gets it (driven
        and enabled) and return the new sample."""
        ...


class StopFlag(Protocol):
    """`threading.Event` or `multiprocessing.Event`: anything that can say stop."""

    def is_set(self) -> bool:
        """True once the server should stop."""
        ...


def _percentile(values: Iterable[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return math.nan
    return ordered[min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1)]


@dataclass
class ServerStats:
    """What happened during one `serve()` run; printed as JSON by `main`."""

    samples_sent: int = 0
    late: int = 0  # samples sent more than LATE_S after their due time
    commands: int = 0  # valid commands applied
    hellos: int = 0
    challenges: int = 0  # CHALLENGEs sent
    joins: int = 0  # JOINs accepted
    versions_sent: int = 0  # VERSION answers to authentic packets of another version
    #: Every dropped datagram by reason: the validation reasons and the state drops
    #: (foreign, flood, replay, stale_echo, unexpected), the names
    #: `controller.device.protocol` and the C core share.
    drops: Counter[str] = field(default_factory=Counter)
    watchdog_releases: int = 0  # transitions from commanded to released
    driver_cutoffs: int = 0  # transitions of the drivers' enable from on to off
    host_changes: int = 0  # the host's port changed at a JOIN after it was first learned
    resyncs: int = 0  # schedule rebased after a stall
    send_errors: int = 0
    host: str = ""  # learned host address, "ip:port"
    streaming_s: float = 0.0
    max_lateness_s: float = 0.0
    lateness_s: deque[float] = field(default_factory=lambda: deque(maxlen=KEEP), repr=False)
    rtt_s: deque[float] = field(default_factory=lambda: deque(maxlen=KEEP), repr=False)

    @property
    def late_fraction(self) -> float:
        """Fraction of samples sent late."""
        return self.late / self.samples_sent if self.samples_sent else 0.0

    @property
    def malformed(self) -> Counter[str]:
        """Drops by a validation reason only (the packet itself was wrong)."""
        return Counter({k: v for k, v in self.drops.items() if k in _VALIDATION})

    def summary(self) -> dict[str, Any]:
        """Counters and percentiles (ms) as plain JSON-able values."""
        d = self.drops
        return {
            "samples_sent": self.samples_sent,
            "late": self.late,
            "late_fraction": self.late_fraction,
            "lateness_p50_ms": 1e3 * _percentile(self.lateness_s, 50),
            "lateness_p99_ms": 1e3 * _percentile(self.lateness_s, 99),
            "lateness_max_ms": 1e3 * self.max_lateness_s,
            "rtt_n": len(self.rtt_s),
            "rtt_p50_ms": 1e3 * _percentile(self.rtt_s, 50),
            "rtt_p99_ms": 1e3 * _percentile(self.rtt_s, 99),
            "rtt_max_ms": 1e3 * max(self.rtt_s, default=math.nan),
            "commands": self.commands,
            "stale_commands": d["stale_echo"],
            "hellos": self.hellos,
            "challenges": self.challenges,
            "joins": self.joins,
            "versions_sent": self.versions_sent,
            "foreign": d["foreign"],
            "flood": d["flood"],
            "unexpected": d["unexpected"],
            "malformed": dict(self.malformed),
            "drops": dict(d),
            "auth_failures": d["auth"],
            "replayed": d["replay"],
            "unknown_version": d["version"],
            "watchdog_releases": self.watchdog_releases,
            "driver_cutoffs": self.driver_cutoffs,
            "host_changes": self.host_changes,
            "resyncs": self.resyncs,
            "send_errors": self.send_errors,
            "host": self.host,
            "streaming_s": self.streaming_s,
        }


_VALIDATION = frozenset(("short", "magic", "length", "auth", "version", "type", "flags",
                         "counts", "status", "reserved", "truth", "identity"))


@dataclass
class _Challenge:
    """The device's one challenge: its bytes, when it was drawn, whether it was spent."""

    value: bytes
    drawn_at: float
    spent: bool = False


class DeviceServer:
    """One simulated exoskeleton on one UDP socket. `run()` until stopped."""

    def __init__(
        self,
        sock: socket.socket,
        model: ExoskeletonModel,
        host_address: str,
        loop: bool,
        duration: float | None,
        stop: StopFlag,
        key: bytes,
        rate_factor: int = 1,
        unique_id: bytes | None = None,
    ) -> None:
        if rate_factor < 1:
            raise ValueError(f"rate_factor must be >= 1, got {rate_factor}")
        self.sock = sock
        self.key = key
        #: This boot of the device; samples carry it, JOINs and commands must name it.
        self.session = new_session()
        self.unique_id = simulated_unique_id(key) if unique_id is None else unique_id
        #: Fault probe: each model period is sent as this many samples, evenly spaced
        #: in real and device time (a device sending too fast, with honest times).
        self.rate_factor = rate_factor
        self._last_sim: Sample | None = None
        self.model = model
        self.host_ip = socket.gethostbyname(host_address)
        self.host_port: int | None = None
        self.loop = loop
        self.duration = duration
        self.stop = stop
        self.stats = ServerStats()
        #: The one host session (None before the first JOIN) and its last host_seq.
        self.host_session: int | None = None
        self._last_host_seq = 0
        self._challenge: _Challenge | None = None
        self._version_sent_at = -math.inf
        self._budget = AUTH_BUDGET
        self._locks = (False, False)
        self._stop_heartbeat = False
        self._cmd_seq = -1
        #: Due time of the sample the latest applied command echoed (its `t` on this
        #: clock): the outputs stay on until WATCHDOG_S after it (None: released).
        self._alive_from: float | None = None
        self._released = True
        #: (wire seq, sent at, due at) of the latest samples: freshness and round trips
        #: count from the send time, the watchdog from the due time (never later).
        self._sent: deque[tuple[int, float, float]] = deque(maxlen=SENT_RING)
        # The heartbeat output and the monostable on the drivers' enable: off at boot.
        self._heartbeat = 0
        self._last_edge = -math.inf
        self._drivers_on = False

    def run(self) -> ServerStats:
        """Wait for a host to join, then stream until stopped, finished or out of time."""
        began = time.monotonic()
        end = math.inf if self.duration is None else began + self.duration
        idle = began
        while self.host_port is None:
            if self.stop.is_set() or time.monotonic() >= end:
                return self.stats
            # One idle period: a fresh authentication budget and a heartbeat edge.
            idle += self.model.dt
            self._budget = AUTH_BUDGET
            self._beat(time.monotonic())
            self._wait_and_receive(min(idle, end))
            if time.monotonic() - idle > RESYNC_S:
                idle = time.monotonic()
        dt = self.model.dt / self.rate_factor
        start = time.monotonic()
        k = 0
        while not self.stop.is_set():
            due = start + k * dt
            if due >= end:
                break
            self._wait_and_receive(due)
            if self.stop.is_set():
                break
            now = time.monotonic()
            if now - due > RESYNC_S:
                self.stats.resyncs += 1
                start = now - k * dt
                due = now
            self._tick(k, due)
            k += 1
            if self.model.finished and not self.loop:
                break
        self.stats.streaming_s = time.monotonic() - start
        return self.stats

    def _beat(self, at: float) -> None:
        """Toggle the heartbeat output unless the applied command stopped it; the
        monostable then holds the drivers' enable until `at + HEARTBEAT_HOLD_S`."""
        if not self._stop_heartbeat:
            self._heartbeat ^= 1
            self._last_edge = at

    def _drivers_enabled(self, at: float) -> bool:
        on = at - self._last_edge < HEARTBEAT_HOLD_S
        if self._drivers_on and not on:
            self.stats.driver_cutoffs += 1
        self._drivers_on = on
        return on

    def _tick(self, k: int, due: float) -> None:
        """Apply the watchdog, toggle the heartbeat, advance the model one period with
        what the mechanism gets, and send the sample."""
        self._budget = AUTH_BUDGET
        now = time.monotonic()
        alive = self._alive_from is not None and now - self._alive_from <= WATCHDOG_S
        if alive:
            left, right = self._locks
            self._released = False
        else:
            left = right = False
            self._stop_heartbeat = False  # the heartbeat resumes when the watchdog releases
            if not self._released:
                self.stats.watchdog_releases += 1
            self._released = True
        # The schedule's time, not the wake-up's: the monostable's 30 ms are then exact.
        self._beat(due)
        enabled = self._drivers_enabled(due)
        command = LockCommand(self._cmd_seq, left and enabled, right and enabled)
        if k % self.rate_factor == 0 or self._last_sim is None:
            self._last_sim = self.model.tick(command)
        sim = self._last_sim
        # The device knows what it drives (solenoid bits mirror its outputs) and reads
        # the drivers' enable back.
        status = (sim.status & ~SOLENOIDS) | (Status.SOLENOID_LEFT if left else 0)
        status |= Status.SOLENOID_RIGHT if right else 0
        if not alive:
            status |= Status.WATCHDOG_RELEASED
        if self._stop_heartbeat:
            status |= Status.HEARTBEAT_STOPPED
        if not enabled:
            status |= Status.DRIVERS_OFF
        dt = self.model.dt / self.rate_factor
        wire = Sample(seq=k, t=k * dt, counts=sim.counts, status=Status(status), truth=sim.truth)
        assert self.host_port is not None and self.host_session is not None
        d = self.stats.drops
        try:
            data = encode_sample(wire, self.key, self.session, self.host_session,
                                 d["auth"], d["replay"], d["stale_echo"])
            self.sock.sendto(data, (self.host_ip, self.host_port))
        except (OSError, ProtocolError):
            # A model that produced an unencodable sample must not stop the device; the
            # host sees the missing sequence number as a gap.
            self.stats.send_errors += 1
        sent = time.monotonic()
        self._sent.append((k % SEQ_MODULUS, sent, min(due, sent)))
        lateness = sent - due
        self.stats.samples_sent += 1
        self.stats.lateness_s.append(lateness)
        self.stats.max_lateness_s = max(self.stats.max_lateness_s, lateness)
        if lateness > LATE_S:
            self.stats.late += 1

    def _wait_and_receive(self, until: float) -> None:
        """Handle datagrams as they arrive until the monotonic time `until`."""
        while True:
            remaining = until - time.monotonic()
            # select() takes microseconds; socket timeouts would round up to whole ms.
            ready, _, _ = select.select([self.sock], [], [], max(min(remaining, 0.05), 0.0))
            if ready:
                self._drain()
            if remaining <= 0 or self.stop.is_set():
                return

    def _drain(self) -> None:
        for _ in range(DRAIN_MAX):
            try:
                data, addr = self.sock.recvfrom(MAX_PACKET + 1, socket.MSG_DONTWAIT)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                continue  # ICMP error reports; nothing to do on a datagram socket
            self._handle(data, str(addr[0]), int(addr[1]), time.monotonic())

    def _send(self, data: bytes, ip: str, port: int) -> None:
        try:
            self.sock.sendto(data, (ip, port))
        except OSError:
            self.stats.send_errors += 1

    def _handle(self, data: bytes, ip: str, port: int, now: float) -> None:
        """One datagram through the device's rules, in the documented order."""
        drops = self.stats.drops
        if ip != self.host_ip:
            drops["foreign"] += 1
            return
        if self._budget <= 0:
            drops["flood"] += 1
            return
        self._budget -= 1
        try:
            frame = decode_frame(data, self.key)
        except ProtocolError as exc:
            drops[exc.reason] += 1
            if exc.reason == "version" and now - self._version_sent_at >= VERSION_GAP_S:
                self._version_sent_at = now
                self._send(encode_version(VersionPacket(LOWEST_VERSION, VERSION), self.key),
                           ip, port)
                self.stats.versions_sent += 1
            return
        packet = frame.packet
        if isinstance(packet, HelloPacket):
            self._on_hello(packet, frame.sender, ip, port, now)
        elif isinstance(packet, JoinPacket):
            self._on_join(packet, frame.sender, frame.receiver, ip, port, now)
        elif isinstance(packet, CommandPacket):
            self._on_command(packet, frame.sender, frame.receiver, now)
        else:
            drops["unexpected"] += 1

    def _on_hello(self, packet: HelloPacket, sender: int, ip: str, port: int,
                  now: float) -> None:
        # Every authentic HELLO within the budget is answered: the budget bounds the
        # work, the answer goes to the host's IP only, and a limit shared by all sources
        # would let replayed HELLOs take every answer and keep the host from joining.
        self.stats.hellos += 1
        c = self._challenge
        if c is None or c.spent or now - c.drawn_at > CHALLENGE_REDRAW_S:
            c = self._challenge = _Challenge(secrets.token_bytes(CHALLENGE_BYTES), now)
        answer = ChallengePacket(hello_seq=packet.host_seq, challenge=c.value,
                                 unique_id=self.unique_id, firmware=FIRMWARE)
        self._send(encode_challenge(answer, self.key, self.session, sender), ip, port)
        self.stats.challenges += 1

    def _on_join(self, packet: JoinPacket, sender: int, receiver: int, ip: str, port: int,
                 now: float) -> None:
        c = self._challenge
        if (receiver != self.session or c is None
                or not hmac.compare_digest(packet.challenge, c.value)
                or c.spent or now - c.drawn_at > CHALLENGE_LIFETIME_S):
            self.stats.drops["replay"] += 1
            return
        c.spent = True
        self.stats.joins += 1
        self.host_session = sender
        self._last_host_seq = packet.host_seq
        if self.host_port is not None and port != self.host_port:
            self.stats.host_changes += 1
        self.host_port = port
        self.stats.host = f"{ip}:{port}"
        # A new session inherits no lock: released, the watchdog starts released.
        self._locks = (False, False)
        self._stop_heartbeat = False
        self._alive_from = None
        self._sent.clear()

    def _on_command(self, packet: CommandPacket, sender: int, receiver: int,
                    now: float) -> None:
        drops = self.stats.drops
        if (receiver != self.session or sender != self.host_session
                or seq_diff(packet.host_seq, self._last_host_seq) <= 0):
            drops["replay"] += 1
            return
        echoed = next((s for s in self._sent if s[0] == packet.echo_seq), None)
        if echoed is None or now - echoed[1] > FRESH_S:
            drops["stale_echo"] += 1
            return
        _, sent_at, due_at = echoed
        self._last_host_seq = packet.host_seq
        self._locks = (packet.lock_left, packet.lock_right)
        self._stop_heartbeat = packet.stop_heartbeat
        self._cmd_seq = packet.host_seq
        # The watchdog counts from the echoed sample's time, not from this arrival.
        self._alive_from = due_at
        self.stats.commands += 1
        self.stats.rtt_s.append(now - sent_at)


def _warm_up(model: ExoskeletonModel) -> None:
    """Pay one-time costs (numba loading its compiled code: ~0.2 s) before the first
    sample is due, on a throwaway copy so the real model's timeline does not move."""
    hook = getattr(model, "warm_up", None)
    if callable(hook):
        hook()
        return
    try:
        copy.deepcopy(model).tick(None)
    except Exception:  # a model that cannot be copied just starts cold
        return


def request_realtime(priority: int = 10) -> str:
    """Ask Linux for SCHED_FIFO, as firmware would have. On a shared machine a normally
    scheduled process can wait a few ms behind CPU-bound neighbours each time a packet
    wakes it; a real-time one does not. Returns what happened, for the log."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as exc:
        return f"real-time scheduling not available ({exc}); running normally"
    return f"running with SCHED_FIFO priority {priority}"


def _default_bind(host_address: str) -> str:
    return "127.0.0.1" if host_address.startswith("127.") else "0.0.0.0"


def serve(
    port: int,
    seed: int,
    script: str,
    host_address: str = "127.0.0.1",
    precompression_pct: float = 25.0,
    loop: bool = True,
    duration: float | None = None,
    stop_event: StopFlag | None = None,
    *,
    model: ExoskeletonModel | None = None,
    bind_address: str | None = None,
    key: bytes,
    rate_factor: int = 1,
    unique_id: bytes | None = None,
    emg_lsl: bool = False,
) -> ServerStats:
    """Run the simulated exoskeleton on UDP `port` for the host at `host_address`.

    Returns when `stop_event` is set, SIGINT/SIGTERM arrives (main thread only), the
    script ends (`loop=False`) or `duration` seconds after the call. `model` replaces
    the `SimulatedExoskeleton` built from seed/script (tests use a stub). `key` is the
    link key shared with the host; `rate_factor` > 1 makes a device that sends that
    many times too fast (a fault probe); `unique_id` (16 bytes) the identity reported
    in CHALLENGEs (default: derived from the key, as the C simulator does).
    """
    if model is None:
        from controller.sim.exoskeleton import SimulatedExoskeleton

        model = SimulatedExoskeleton(
            seed=seed, script=script, precompression_pct=precompression_pct, loop=loop
        )
    if emg_lsl:  # the wearer's muscles on LSL, as an EMG amplifier (emg_amplifier.py)
        from controller.sim.emg_amplifier import tap

        model = tap(model)
    _warm_up(model)
    signalled = SignalSafeFlag()
    stop: StopFlag = signalled if stop_event is None else _Either(signalled, stop_event)
    previous: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():

        def _on_signal(signum: int, frame: FrameType | None) -> None:
            signalled.set()

        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, _on_signal)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind((bind_address or _default_bind(host_address), port))
        sock.setblocking(False)
        return DeviceServer(sock, model, host_address, loop, duration, stop, key,
                            rate_factor, unique_id).run()
    finally:
        sock.close()
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@dataclass(frozen=True)
class _Either:
    """Stop when either flag is set (our signal flag or the caller's event)."""

    a: StopFlag
    b: StopFlag

    def is_set(self) -> bool:
        return self.a.is_set() or self.b.is_set()


def main(argv: Sequence[str] | None = None) -> int:
    """`exostudy device-sim`: serve until interrupted; print the run's statistics as JSON."""
    from controller.help_format import DefaultsHelpFormatter

    parser = argparse.ArgumentParser(
        prog="exostudy device-sim", description="Simulated exoskeleton speaking the UDP protocol.",
        formatter_class=DefaultsHelpFormatter)
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help="UDP port to listen on")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--script", default="paper-evaluation", help="simulated wearer's script")
    parser.add_argument("--host", default="127.0.0.1", help="the only IP commands are taken from")
    parser.add_argument("--bind", default=None, help="local address (default: by host address)")
    parser.add_argument("--precompression", type=float, default=25.0, help="percent of 22 mm")
    parser.add_argument("--no-loop", action="store_true", help="stop when the script ends")
    parser.add_argument("--duration", type=float, default=None, help="stop after this many s")
    parser.add_argument(
        "--realtime", action="store_true", help="request SCHED_FIFO (needs CAP_SYS_NICE)"
    )
    parser.add_argument("--key-file", required=True, type=Path,
                        help="the link key shared with the host (64 hex digits, mode 0600)")
    parser.add_argument("--rate-factor", type=int, default=1,
                        help="fault probe: send each sample this many times, as fast")
    parser.add_argument("--emg-lsl", action="store_true",
                        help="also publish the wearer's simulated EMG on LSL (16 ch, 2 kHz)")
    parser.add_argument("--device-id", default=None,
                        help="unique id reported in CHALLENGEs, 1..32 hex digits (default: "
                             "derived from the key)")
    args = parser.parse_args(argv)
    try:
        key = load_key(args.key_file)
        unique_id = None if args.device_id is None else parse_unique_id(args.device_id)
    except ValueError as exc:
        parser.error(str(exc))
    if not 1 <= args.rate_factor <= 100:
        parser.error("--rate-factor must be within 1..100")
    if args.realtime:
        print(f"device-sim: {request_realtime()}", file=sys.stderr, flush=True)
    print(
        f"device-sim: listening on {args.bind or _default_bind(args.host)}:{args.port}, "
        f"host {args.host}, script {args.script!r}, seed {args.seed}",
        file=sys.stderr,
        flush=True,
    )
    stats = serve(
        port=args.port,
        seed=args.seed,
        script=args.script,
        host_address=args.host,
        precompression_pct=args.precompression,
        loop=not args.no_loop,
        duration=args.duration,
        bind_address=args.bind,
        key=key,
        rate_factor=args.rate_factor,
        unique_id=unique_id,
        emg_lsl=args.emg_lsl,
    )
    print(json.dumps(stats.summary()), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
