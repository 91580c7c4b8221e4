"""The simulated exoskeleton as a network device: the device side of `docs/device-protocol.md`.

It behaves like the firmware would, so the host cannot tell the difference: samples at
100 Hz on an absolute schedule, commands only from the configured host address and only
with a valid authentication tag (the key shared with the host), never a replayed or
stale one (`controller.device.auth`), the 100 ms watchdog that drops the solenoids, and
a count of every packet sent late or dropped. The host's port and session are learned
from its first authentic HELLO or COMMAND (from the configured IP); the simulated
wearer starts moving at that moment, so a given seed gives the host the same data every
run.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
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

from controller.device.auth import PeerSessions, load_key, new_session
from controller.device.base import LockCommand, Sample, Status
from controller.device.protocol import (
    DEFAULT_PORT,
    MAX_PACKET,
    CommandPacket,
    HelloPacket,
    ProtocolError,
    decode_frame,
    encode_sample,
    seq_diff,
)
from controller.stop_flag import SignalSafeFlag

WATCHDOG_S = 0.100  # no valid command for this long: solenoids off, WATCHDOG_RELEASED
LATE_S = 0.002  # a sample sent more than this after its due time counts as late
RESYNC_S = 0.25  # further behind than this (process stalled): rebase the schedule, no burst
RTT_RING = 1024  # send times kept for matching echoed sequence numbers
KEEP = 360_000  # lateness and round-trip values kept for percentiles: the last hour
SOLENOIDS = Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT


class ExoskeletonModel(Protocol):
    """What the server needs from a simulated exoskeleton (`SimulatedExoskeleton`)."""

    dt: float

    @property
    def finished(self) -> bool:
        """The script has ended (never true when looping)."""
        ...

    def tick(self, command: LockCommand | None) -> Sample:
        """Advance one period with this solenoid command and return the new sample."""
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
    stale_commands: int = 0  # valid but older than the last applied one
    hellos: int = 0
    foreign: int = 0  # datagrams from any IP but the configured host
    unexpected: int = 0  # valid packets of a type a host never sends
    malformed: Counter[str] = field(default_factory=Counter)  # by ProtocolError reason
    # Authentic but seen before, from a replaced host session, or addressed to an
    # earlier boot of this device.
    replayed: int = 0
    watchdog_releases: int = 0  # transitions from commanded to released
    host_changes: int = 0  # the host's port changed after it was first learned
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

    def summary(self) -> dict[str, Any]:
        """Counters and percentiles (ms) as plain JSON-able values."""
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
            "stale_commands": self.stale_commands,
            "hellos": self.hellos,
            "foreign": self.foreign,
            "unexpected": self.unexpected,
            "malformed": dict(self.malformed),
            "auth_failures": self.malformed.get("auth", 0),
            "replayed": self.replayed,
            "unknown_version": self.malformed.get("version", 0),
            "watchdog_releases": self.watchdog_releases,
            "host_changes": self.host_changes,
            "resyncs": self.resyncs,
            "send_errors": self.send_errors,
            "host": self.host,
            "streaming_s": self.streaming_s,
        }


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
    ) -> None:
        if rate_factor < 1:
            raise ValueError(f"rate_factor must be >= 1, got {rate_factor}")
        self.sock = sock
        self.key = key
        #: This boot of the device; samples carry it, commands must name it.
        self.session = new_session()
        self.hosts = PeerSessions()
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
        self._last_host_seq: int | None = None
        self._locks = (False, False)
        self._cmd_seq = -1
        self._last_cmd_at: float | None = None
        self._released = True
        self._sent_at = [math.nan] * RTT_RING
        self._sent_seq = [-1] * RTT_RING

    def run(self) -> ServerStats:
        """Wait for the host, then stream until stopped, finished or out of time."""
        began = time.monotonic()
        end = math.inf if self.duration is None else began + self.duration
        while self.host_port is None:
            if self.stop.is_set() or time.monotonic() >= end:
                return self.stats
            self._wait_and_receive(min(time.monotonic() + 0.05, end))
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

    def _tick(self, k: int, due: float) -> None:
        """Apply the watchdog, advance the model one period and send the sample."""
        now = time.monotonic()
        alive = self._last_cmd_at is not None and now - self._last_cmd_at <= WATCHDOG_S
        if alive:
            command = LockCommand(self._cmd_seq, *self._locks)
            self._released = False
        else:
            command = LockCommand(self._cmd_seq, False, False)
            if not self._released:
                self.stats.watchdog_releases += 1
            self._released = True
        if k % self.rate_factor == 0 or self._last_sim is None:
            self._last_sim = self.model.tick(command)
        sim = self._last_sim
        # The device knows what it drives: solenoid bits mirror the command applied.
        status = (sim.status & ~SOLENOIDS) | (Status.SOLENOID_LEFT if command.lock_left else 0)
        status |= Status.SOLENOID_RIGHT if command.lock_right else 0
        if not alive:
            status |= Status.WATCHDOG_RELEASED
        dt = self.model.dt / self.rate_factor
        wire = Sample(seq=k, t=k * dt, counts=sim.counts, status=Status(status), truth=sim.truth)
        assert self.host_port is not None and self.hosts.current is not None
        try:
            data = encode_sample(wire, self.key, self.session, self.hosts.current,
                                 self.stats.malformed.get("auth", 0), self.stats.replayed)
            self.sock.sendto(data, (self.host_ip, self.host_port))
        except (OSError, ProtocolError):
            # A model that produced an unencodable sample must not stop the device; the
            # host sees the missing sequence number as a gap.
            self.stats.send_errors += 1
        sent = time.monotonic()
        slot = k % RTT_RING
        self._sent_at[slot], self._sent_seq[slot] = sent, k % (1 << 32)
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
        while True:
            try:
                data, addr = self.sock.recvfrom(MAX_PACKET + 1, socket.MSG_DONTWAIT)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                continue  # ICMP error reports; nothing to do on a datagram socket
            self._handle(data, str(addr[0]), int(addr[1]), time.monotonic())

    def _handle(self, data: bytes, ip: str, port: int, now: float) -> None:
        if ip != self.host_ip:
            self.stats.foreign += 1
            return
        try:
            frame = decode_frame(data, self.key)
        except ProtocolError as exc:
            self.stats.malformed[exc.reason] += 1
            return
        packet = frame.packet
        if not isinstance(packet, CommandPacket | HelloPacket):
            self.stats.unexpected += 1
            return
        # A COMMAND must name this boot of the device (a recorded one names an earlier
        # boot); a HELLO may not know it yet. A new host session may start with either.
        if isinstance(packet, CommandPacket) and frame.receiver != self.session:
            self.stats.replayed += 1
            return
        verdict = self.hosts.check(frame.sender, packet.host_seq)
        if verdict == "replay":
            self.stats.replayed += 1
            return
        if port != self.host_port or verdict == "new":
            if self.host_port is not None and port != self.host_port:
                self.stats.host_changes += 1
            self.host_port = port
            self.stats.host = f"{ip}:{port}"
            self._last_host_seq = None
        if isinstance(packet, HelloPacket):
            # HELLO restarts the host's sequence, so a restarted host is not "stale".
            self.stats.hellos += 1
            self._last_host_seq = packet.host_seq
            return
        if self._last_host_seq is not None and seq_diff(packet.host_seq, self._last_host_seq) <= 0:
            self.stats.stale_commands += 1
            return
        self._last_host_seq = packet.host_seq
        self._locks = (packet.lock_left, packet.lock_right)
        self._cmd_seq = packet.host_seq
        self._last_cmd_at = now
        self.stats.commands += 1
        if packet.echo_seq is not None:
            slot = packet.echo_seq % RTT_RING
            if self._sent_seq[slot] == packet.echo_seq:
                self.stats.rtt_s.append(now - self._sent_at[slot])
                self._sent_seq[slot] = -1  # one round trip per sample


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
) -> ServerStats:
    """Run the simulated exoskeleton on UDP `port` for the host at `host_address`.

    Returns when `stop_event` is set, SIGINT/SIGTERM arrives (main thread only), the
    script ends (`loop=False`) or `duration` seconds after the call. `model` replaces
    the `SimulatedExoskeleton` built from seed/script (tests use a stub). `key` is the
    link key shared with the host; `rate_factor` > 1 makes a device that sends that
    many times too fast (a fault probe).
    """
    if model is None:
        from controller.sim.exoskeleton import SimulatedExoskeleton

        model = SimulatedExoskeleton(
            seed=seed, script=script, precompression_pct=precompression_pct, loop=loop
        )
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
                            rate_factor).run()
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
    args = parser.parse_args(argv)
    try:
        key = load_key(args.key_file)
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
    )
    print(json.dumps(stats.summary()), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
