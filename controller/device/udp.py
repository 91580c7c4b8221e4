"""The exoskeleton over UDP: the host side of `docs/device-protocol.md`.

The worker reads one sample per tick and answers with one command. This class keeps
the link honest: it only accepts datagrams from the configured device address, drops
malformed, duplicate and out-of-order packets, extends the 32-bit wire sequence to a
host sequence that never goes backwards, and counts every irregularity so that
`faults()` can tell the operator what the link is doing. It never blocks on send.
"""

from __future__ import annotations

import socket
import time
from collections import Counter
from dataclasses import dataclass, field, replace

from controller.device.base import NO_LOCK, Device, DeviceError, LockCommand, Sample
from controller.device.protocol import (
    DEFAULT_PORT,
    MAX_PACKET,
    SEQ_MODULUS,
    CommandPacket,
    HelloPacket,
    ProtocolError,
    decode,
    encode_command,
    encode_hello,
    seq_diff,
)

HELLO_INTERVAL_S = 0.5  # announce ourselves this often while no command is being sent
OUTAGE_S = 0.05  # no sample for this long (5 periods) is reported as a link outage
RESTART_AFTER = 25  # this many consecutive older sequence numbers mean the device restarted


@dataclass
class LinkStats:
    """Cumulative link counters since `open()`; `faults()` reports their increments."""

    samples: int = 0
    gaps: int = 0  # sequence jumps
    missing: int = 0  # samples lost inside those jumps
    duplicates: int = 0
    stale: int = 0  # older than the last accepted sample (reordered or delayed)
    restarts: int = 0  # device sequence restarted; host sequence continued
    malformed: Counter[str] = field(default_factory=Counter)  # by ProtocolError reason
    foreign: int = 0  # datagrams from any address but the device's
    unexpected: int = 0  # valid packets of a type a device never sends
    outages: int = 0
    commands_sent: int = 0
    hellos_sent: int = 0
    send_errors: int = 0

    def copy(self) -> LinkStats:
        """A snapshot (the counter is copied, not shared)."""
        return replace(self, malformed=Counter(self.malformed))


def _is_loopback(host: str) -> bool:
    return host.startswith("127.") or host == "localhost"


class UdpDevice(Device):
    """An exoskeleton (real firmware or `exostudy device-sim`) reached over UDP."""

    kind = "udp"

    def __init__(
        self,
        device_host: str = "127.0.0.1",
        device_port: int = DEFAULT_PORT,
        local_port: int = 0,
        local_host: str | None = None,
    ) -> None:
        self.device_host = device_host
        self.device_port = device_port
        self.local_port = local_port
        # Loopback devices get a loopback-only socket; others need a routable interface.
        self.local_host = local_host or ("127.0.0.1" if _is_loopback(device_host) else "0.0.0.0")
        self.stats = LinkStats()
        self._reported = LinkStats()
        self._events: list[str] = []
        self._sock: socket.socket | None = None
        self._device_addr: tuple[str, int] = (device_host, device_port)
        self._host_seq = 0
        self._last_wire: int | None = None  # wire sequence of the last accepted sample
        self._host_ext = -1  # extended (host) sequence of the last accepted sample
        self._backwards = 0  # consecutive samples older than the last accepted one
        self._last_send = -float("inf")
        self._last_sample_at: float | None = None
        self._in_outage = False

    @property
    def address(self) -> tuple[str, int]:
        """The local (ip, port) samples arrive at; the device learns it from our packets."""
        if self._sock is None:
            raise DeviceError("UdpDevice is not open")
        host, port = self._sock.getsockname()[:2]
        return str(host), int(port)

    def open(self) -> None:
        """Bind the local socket and say HELLO so the device starts streaming to us."""
        if self._sock is not None:
            return
        try:
            ip = socket.gethostbyname(self.device_host)
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.bind((self.local_host, self.local_port))
        except OSError as exc:
            raise DeviceError(f"cannot open UDP link to {self.device_host}: {exc}") from exc
        self._device_addr = (ip, self.device_port)
        self._sock = sock
        self._send_hello()

    def read(self, timeout: float) -> Sample | None:
        """The next in-order sample, or None after `timeout` seconds without one."""
        sock = self._require_open()
        deadline = time.monotonic() + max(timeout, 0.0)
        while True:
            now = time.monotonic()
            if now - self._last_send >= HELLO_INTERVAL_S:
                self._send_hello()
            self._check_outage(now)
            remaining = deadline - now
            # Also wake for the next HELLO (nobody may be sending commands) and to notice
            # an outage as it starts.
            wait = min(remaining, self._last_send + HELLO_INTERVAL_S - now)
            if self._last_sample_at is not None and not self._in_outage:
                wait = min(wait, self._last_sample_at + OUTAGE_S + 1e-4 - now)
            sock.settimeout(max(wait, 0.0))
            try:
                data, addr = sock.recvfrom(MAX_PACKET + 1)
            except (TimeoutError, BlockingIOError):
                if wait < remaining:
                    continue
                return None
            except OSError as exc:
                # ICMP errors (e.g. port unreachable) surface here on some systems.
                self._events.append(f"receive error: {exc}")
                if remaining <= 0:
                    return None
                continue
            sample = self._accept(data, (str(addr[0]), int(addr[1])))
            if sample is not None:
                return sample
            if remaining <= 0:
                return None

    def send(self, command: LockCommand) -> None:
        """Send a COMMAND carrying the echo of the last sample; drops rather than blocks."""
        self._require_open()
        packet = CommandPacket(
            host_seq=self._next_host_seq(),
            lock_left=command.lock_left,
            lock_right=command.lock_right,
            echo_seq=self._last_wire,
        )
        if self._sendto(encode_command(packet)):
            self.stats.commands_sent += 1

    def release(self) -> None:
        """Send an all-off command (twice, against a single lost datagram). Never raises:
        the device's 100 ms watchdog is the backstop when this cannot be delivered."""
        try:
            if self._sock is not None:
                self.send(NO_LOCK)
                self.send(NO_LOCK)
        except Exception as exc:  # release must never raise
            self._events.append(f"release failed: {exc}")

    def close(self) -> None:
        """Release, then close the socket. Safe to call twice."""
        self.release()
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def faults(self) -> list[str]:
        """Link problems since the last call, one line per kind, with counts."""
        s, r = self.stats, self._reported
        out = list(self._events)
        self._events.clear()
        if s.gaps > r.gaps:
            out.append(
                f"{s.gaps - r.gaps} sequence gap(s), {s.missing - r.missing} sample(s) missing"
            )
        if s.duplicates > r.duplicates:
            out.append(f"{s.duplicates - r.duplicates} duplicate sample(s) dropped")
        if s.stale > r.stale:
            out.append(f"{s.stale - r.stale} out-of-order sample(s) dropped")
        new_bad = s.malformed - r.malformed
        if new_bad:
            detail = ", ".join(f"{k}: {v}" for k, v in sorted(new_bad.items()))
            out.append(f"{sum(new_bad.values())} malformed packet(s) dropped ({detail})")
        if s.foreign > r.foreign:
            out.append(f"{s.foreign - r.foreign} packet(s) from foreign addresses ignored")
        if s.unexpected > r.unexpected:
            out.append(f"{s.unexpected - r.unexpected} unexpected packet type(s) from the device")
        if s.send_errors > r.send_errors:
            out.append(f"{s.send_errors - r.send_errors} command(s) could not be sent")
        self._reported = s.copy()
        return out

    # -- internals -------------------------------------------------------------------

    def _require_open(self) -> socket.socket:
        if self._sock is None:
            raise DeviceError("UdpDevice is not open")
        return self._sock

    def _next_host_seq(self) -> int:
        self._host_seq = (self._host_seq + 1) % SEQ_MODULUS
        return self._host_seq

    def _sendto(self, data: bytes) -> bool:
        sock = self._require_open()
        self._last_send = time.monotonic()  # the attempt counts: no HELLO storm on errors
        try:
            sock.setblocking(False)  # a timeout left by read() would make sendto poll first
            sock.sendto(data, socket.MSG_DONTWAIT, self._device_addr)
        except OSError:
            self.stats.send_errors += 1
            return False
        return True

    def _send_hello(self) -> None:
        if self._sendto(encode_hello(HelloPacket(host_seq=self._next_host_seq()))):
            self.stats.hellos_sent += 1

    def _check_outage(self, now: float) -> None:
        last = self._last_sample_at
        if last is not None and not self._in_outage and now - last > OUTAGE_S:
            self._in_outage = True
            self.stats.outages += 1
            self._events.append(f"link outage: no sample for more than {1000 * OUTAGE_S:.0f} ms")

    def _accept(self, data: bytes, addr: tuple[str, int]) -> Sample | None:
        """Filter one datagram; return the sample it carries if the worker should see it."""
        if addr != self._device_addr:
            self.stats.foreign += 1
            return None
        try:
            packet = decode(data)
        except ProtocolError as exc:
            self.stats.malformed[exc.reason] += 1
            return None
        if not isinstance(packet, Sample):
            self.stats.unexpected += 1
            return None
        now = time.monotonic()
        if self._last_wire is None:
            self._host_ext = packet.seq - 1  # host sequence starts equal to the wire's
            step = 1
        else:
            step = seq_diff(packet.seq, self._last_wire)
            if step <= 0:
                self._backwards += 1
                if self._backwards < RESTART_AFTER:
                    if step == 0:
                        self.stats.duplicates += 1
                    else:
                        self.stats.stale += 1
                    return None
                # A run of "old" samples is a device that started counting again.
                self.stats.restarts += 1
                self._events.append(
                    f"device sequence restarted at {packet.seq}; host sequence continues"
                )
                step = 1
            elif step > 1:
                self.stats.gaps += 1
                self.stats.missing += step - 1
        self._backwards = 0
        if self._in_outage and self._last_sample_at is not None:
            gap_ms = 1000 * (now - self._last_sample_at)
            self._events.append(f"link outage ended: samples resumed after {gap_ms:.0f} ms")
        self._in_outage = False
        self._last_sample_at = now
        self._last_wire = packet.seq
        self._host_ext += step
        self.stats.samples += 1
        return replace(packet, seq=self._host_ext)
