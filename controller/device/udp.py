"""The exoskeleton over UDP: the host side of `docs/device-protocol.md`.

The worker reads one sample per tick and answers with one command. This class keeps
the link honest: it only accepts datagrams from the configured device address, drops
packets that fail the authentication tag (forged or damaged), replays (a sequence number
of the device's session already seen, a session of the device replaced earlier, a sample
addressed to an earlier session of this host), malformed and out-of-order packets,
extends the 32-bit wire sequence to a host sequence that never goes backwards, and
counts every irregularity so that `faults()` and `link_counters()` can tell the operator
what the link is doing. A device restart is a new device session, authenticated, not a
guess from sequence numbers. It never blocks on send.
"""

from __future__ import annotations

import socket
import time
from collections import Counter
from dataclasses import dataclass, field, replace

from controller.device.auth import KEY_BYTES, PeerSessions, new_session
from controller.device.base import NO_LOCK, Device, DeviceError, LockCommand, Sample
from controller.device.protocol import (
    DEFAULT_PORT,
    MAX_PACKET,
    SEQ_MODULUS,
    CommandPacket,
    HelloPacket,
    ProtocolError,
    decode_frame,
    encode_command,
    encode_hello,
    seq_diff,
)

HELLO_INTERVAL_S = 0.5  # announce ourselves this often while no command is being sent
OUTAGE_S = 0.05  # no sample for this long (5 periods) is reported as a link outage


@dataclass
class LinkStats:
    """Cumulative link counters since `open()`; `faults()` reports their increments."""

    samples: int = 0
    gaps: int = 0  # sequence jumps
    missing: int = 0  # samples lost inside those jumps
    duplicates: int = 0  # authentic, but a sequence number of this session seen before
    stale: int = 0  # older than the last accepted sample (reordered or delayed)
    restarts: int = 0  # a new device session; host sequence continued
    replayed: int = 0  # from a replaced device session, or to an earlier host session
    malformed: Counter[str] = field(default_factory=Counter)  # by ProtocolError reason
    # The device's own counts of commands it dropped, as its latest sample reports them.
    device_auth_drops: int = 0
    device_replay_drops: int = 0
    foreign: int = 0  # datagrams from any address but the device's
    unexpected: int = 0  # valid packets of a type a device never sends
    outages: int = 0
    commands_sent: int = 0
    commands_unaddressed: int = 0  # not sent: no device session known yet
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
        *,
        key: bytes,
    ) -> None:
        if len(key) != KEY_BYTES:
            raise DeviceError(f"the device key must be {KEY_BYTES} bytes, got {len(key)}")
        self.key = key
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
        self.session = new_session()  # this host's session; a new one at every open()
        self.device_sessions = PeerSessions()
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
        self.session = new_session()
        self.device_sessions = PeerSessions()
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
        """Send a COMMAND carrying the echo of the last sample; drops rather than blocks.

        Before the first authentic sample the device's session is unknown, and a COMMAND
        it cannot be addressed to would only be dropped by the device as stale; the
        device starts unlocked, so nothing is sent and the skip is counted."""
        self._require_open()
        if self.device_sessions.current is None:
            self.stats.commands_unaddressed += 1
            return
        packet = CommandPacket(
            host_seq=self._next_host_seq(),
            lock_left=command.lock_left,
            lock_right=command.lock_right,
            echo_seq=self._last_wire,
        )
        if self._sendto(encode_command(packet, self.key, self.session, self._device_session)):
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
        if s.replayed > r.replayed:
            out.append(f"{s.replayed - r.replayed} replayed sample(s) dropped")
        if s.restarts > r.restarts:
            out.append(f"{s.restarts - r.restarts} device restart(s): a new device session")
        if s.device_auth_drops > r.device_auth_drops:
            out.append(f"the device dropped {s.device_auth_drops - r.device_auth_drops} "
                       "command(s) that failed authentication")
        if s.device_replay_drops > r.device_replay_drops:
            out.append(f"the device dropped {s.device_replay_drops - r.device_replay_drops} "
                       "replayed or stale command(s)")
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

    def link_counters(self) -> dict[str, int]:
        """Packets dropped since `open()`, by reason, both sides (see `Device`)."""
        s = self.stats
        out = {"auth": s.malformed.get("auth", 0), "replay": s.replayed + s.duplicates,
               "stale": s.stale, "foreign": s.foreign,
               "malformed": sum(v for k, v in s.malformed.items() if k != "auth"),
               "device_auth": s.device_auth_drops, "device_replay": s.device_replay_drops,
               "device_restarts": s.restarts}
        return out

    @property
    def _device_session(self) -> int:
        return self.device_sessions.current or 0
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
        hello = encode_hello(HelloPacket(host_seq=self._next_host_seq()), self.key,
                             self.session, self._device_session)
        if self._sendto(hello):
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
            frame = decode_frame(data, self.key)
        except ProtocolError as exc:
            self.stats.malformed[exc.reason] += 1
            return None
        packet = frame.packet
        if not isinstance(packet, Sample):
            self.stats.unexpected += 1
            return None
        if frame.receiver != self.session:
            # Authentic, but addressed to an earlier session of this host: recorded and
            # sent again (or left over from before a restart).
            self.stats.replayed += 1
            return None
        verdict = self.device_sessions.check(frame.sender, packet.seq % SEQ_MODULUS)
        if verdict == "replay":
            if frame.sender == self.device_sessions.current:
                self.stats.duplicates += 1
            else:
                self.stats.replayed += 1
            return None
        now = time.monotonic()
        if verdict == "new" or self._last_wire is None:
            if self._last_wire is not None:
                # A new device session: the device restarted. The host sequence continues.
                self.stats.restarts += 1
                self._events.append(
                    f"device restarted (new session) at sequence {packet.seq}; host "
                    "sequence continues")
            else:
                self._host_ext = packet.seq - 1  # host sequence starts equal to the wire's
            step = 1
        else:
            step = seq_diff(packet.seq, self._last_wire)
            if step <= 0:
                self.stats.stale += 1  # reordered: a newer sample was already used
                return None
            if step > 1:
                self.stats.gaps += 1
                self.stats.missing += step - 1
        self.stats.device_auth_drops = frame.device_auth_drops
        self.stats.device_replay_drops = frame.device_replay_drops
        if self._in_outage and self._last_sample_at is not None:
            gap_ms = 1000 * (now - self._last_sample_at)
            self._events.append(f"link outage ended: samples resumed after {gap_ms:.0f} ms")
        self._in_outage = False
        self._last_sample_at = now
        self._last_wire = packet.seq
        self._host_ext += step
        self.stats.samples += 1
        return replace(packet, seq=self._host_ext)
