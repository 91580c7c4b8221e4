"""The exoskeleton over UDP: the host side of `docs/device-protocol.md` (version 3).

The worker reads one sample per tick and answers with one command. This class keeps
the link honest. It joins the device: a HELLO every 100 ms while it has no working
session, one JOIN per CHALLENGE that answers one of its own HELLOs of the last second
(the device's single-use challenge, so a recording cannot open a session), and a new
join after 250 ms without a valid sample. It accepts samples only from the configured
device address, authentic, of the joined device session and addressed to this host's
session, with a sequence number later than the last one used; it extends the 32-bit
wire sequence to a host sequence that never goes backwards, and counts every
irregularity so that `faults()` and `link_counters()` can tell the operator what the
link is doing. A device restart is a new device session in a CHALLENGE, authenticated,
not a guess from sequence numbers. A device that speaks another version says so with
VERSION; one that stays silent is named after 20 HELLOs. It never blocks on send.
"""

from __future__ import annotations

import socket
import time
from collections import Counter, deque
from dataclasses import dataclass, field, replace

from controller.device.auth import KEY_BYTES, key_id, new_session
from controller.device.base import (
    NO_LOCK,
    Device,
    DeviceError,
    DeviceIdentity,
    LockCommand,
    Sample,
)
from controller.device.protocol import (
    CHALLENGE_REDRAW_MS,
    DEFAULT_PORT,
    LOWEST_VERSION,
    MAX_PACKET,
    SEQ_MODULUS,
    VERSION,
    ChallengePacket,
    CommandPacket,
    HelloPacket,
    JoinPacket,
    ProtocolError,
    VersionPacket,
    decode_frame,
    encode_command,
    encode_hello,
    encode_join,
    seq_diff,
)

HELLO_INTERVAL_S = 0.1  # a HELLO this often while there is no working session
HELLO_MEMORY_S = 1.0  # a CHALLENGE must answer a HELLO sent at most this long ago
# A HELLO sent this long after the one before may make the device draw a new challenge
# (it redraws after CHALLENGE_REDRAW_MS; 100 ms less allows for the path's jitter): the
# CHALLENGEs to the HELLOs before it are then forgotten, not answered with a dead JOIN.
HELLO_REDRAW_GAP_S = CHALLENGE_REDRAW_MS / 1000 - 0.1
JOIN_WAIT_S = 0.3  # after a JOIN, a sample is expected within this long
REJOIN_S = 0.25  # no valid sample for this long: join again (same host session)
SILENT_HELLOS = 20  # this many HELLOs without a CHALLENGE: "no version 3 device answers"
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
    # Authentic but not of this link now: a sample of another device session or to
    # another host session, a CHALLENGE to another host session or to a HELLO this
    # session never sent.
    replayed: int = 0
    malformed: Counter[str] = field(default_factory=Counter)  # by ProtocolError reason
    # The device's own drop counts, as its latest sample reports them.
    device_auth_drops: int = 0
    device_replay_drops: int = 0
    device_stale_drops: int = 0
    foreign: int = 0  # datagrams from any address but the device's
    unexpected: int = 0  # valid packets of a type a device never sends
    versions: int = 0  # VERSION packets: the device speaks another protocol version
    outages: int = 0
    joins: int = 0  # JOINs sent (one per accepted CHALLENGE)
    # CHALLENGEs to a HELLO of this session that is older than a second or that a JOIN
    # already answered (the device answered two HELLOs, the path doubled or delayed
    # one, or the host read late): ignored, not a replay.
    late_challenges: int = 0
    commands_sent: int = 0
    commands_unaddressed: int = 0  # not sent: no sample of a joined session to answer
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
        self.key_id = key_id(key)
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
        #: The device session of the last accepted CHALLENGE (None before the first).
        self.device_session: int | None = None
        self._identity: DeviceIdentity | None = None  # once a sample proves the join
        self._offered: DeviceIdentity | None = None  # from the CHALLENGE, before that
        self._hellos: deque[tuple[int, float]] = deque()  # (host_seq, sent at), last 1 s
        self._silent_hellos = 0  # HELLOs since the last accepted CHALLENGE
        self._answered: int | None = None  # the HELLO the last accepted CHALLENGE answered
        self._last_hello = -float("inf")
        self._join_at: float | None = None  # JOIN sent, no sample of it yet
        self._last_sample_at: float | None = None
        self._in_outage = False
        #: What keeps this link from running, for as long as it holds ("" if nothing):
        #: a device of another protocol version, or no version 3 device answering.
        self.problem = ""

    @property
    def address(self) -> tuple[str, int]:
        """The local (ip, port) samples arrive at; the device learns it from our JOIN."""
        if self._sock is None:
            raise DeviceError("UdpDevice is not open")
        host, port = self._sock.getsockname()[:2]
        return str(host), int(port)

    @property
    def identity(self) -> DeviceIdentity | None:
        """The device's identity from its CHALLENGE, once a sample proved the join."""
        return self._identity

    @property
    def joined(self) -> bool:
        """Whether samples of a joined device session are arriving."""
        return self._working(time.monotonic())

    def open(self) -> None:
        """Bind the local socket and say HELLO, which starts the join."""
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
        self.device_session = None
        self._identity = self._offered = None
        self._send_hello(time.monotonic())

    def read(self, timeout: float) -> Sample | None:
        """The next in-order sample, or None after `timeout` seconds without one."""
        sock = self._require_open()
        deadline = time.monotonic() + max(timeout, 0.0)
        while True:
            now = time.monotonic()
            self._check_outage(now)
            wake = self._maintain(now)
            remaining = deadline - now
            # Also wake for the next HELLO and to notice an outage as it starts.
            wait = min(remaining, wake - now)
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
        """Send a COMMAND answering the last sample; drops rather than blocks.

        Without a sample of the joined session there is nothing to answer, and the
        device would drop the command as stale; it starts every session released, so
        nothing is sent and the skip is counted."""
        self._require_open()
        if self.device_session is None or self._last_wire is None:
            self.stats.commands_unaddressed += 1
            return
        packet = CommandPacket(
            host_seq=self._next_host_seq(),
            lock_left=command.lock_left,
            lock_right=command.lock_right,
            echo_seq=self._last_wire,
            stop_heartbeat=command.stop_heartbeat,
        )
        if self._sendto(encode_command(packet, self.key, self.session, self.device_session)):
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
        """Link problems since the last call, one line per kind, with counts; a standing
        problem (`problem`) is repeated on every call for as long as it holds."""
        s, r = self.stats, self._reported
        out = list(self._events)
        self._events.clear()
        if self.problem:
            out.append(self.problem)
        if s.gaps > r.gaps:
            out.append(
                f"{s.gaps - r.gaps} sequence gap(s), {s.missing - r.missing} sample(s) missing"
            )
        if s.duplicates > r.duplicates:
            out.append(f"{s.duplicates - r.duplicates} duplicate sample(s) dropped")
        if s.replayed > r.replayed:
            out.append(f"{s.replayed - r.replayed} replayed packet(s) dropped")
        if s.restarts > r.restarts:
            out.append(f"{s.restarts - r.restarts} device restart(s): a new device session")
        if s.device_auth_drops > r.device_auth_drops:
            out.append(f"the device dropped {s.device_auth_drops - r.device_auth_drops} "
                       "datagram(s) that failed authentication")
        if s.device_replay_drops > r.device_replay_drops:
            out.append(f"the device dropped {s.device_replay_drops - r.device_replay_drops} "
                       "replayed packet(s)")
        if s.device_stale_drops > r.device_stale_drops:
            out.append(f"the device dropped {s.device_stale_drops - r.device_stale_drops} "
                       "stale command(s) (older than 100 ms)")
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
        return {"auth": s.malformed.get("auth", 0), "replay": s.replayed + s.duplicates,
                "stale": s.stale, "foreign": s.foreign,
                "malformed": sum(v for k, v in s.malformed.items() if k != "auth"),
                "version": s.versions,
                "device_auth": s.device_auth_drops, "device_replay": s.device_replay_drops,
                "device_stale": s.device_stale_drops, "device_restarts": s.restarts}

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
        try:
            sock.setblocking(False)  # a timeout left by read() would make sendto poll first
            sock.sendto(data, socket.MSG_DONTWAIT, self._device_addr)
        except OSError:
            self.stats.send_errors += 1
            return False
        return True

    def _working(self, now: float) -> bool:
        """A session works while its samples arrive (or its JOIN is young)."""
        if self._join_at is not None:
            return now - self._join_at < JOIN_WAIT_S
        return self._last_sample_at is not None and now - self._last_sample_at < REJOIN_S

    def _maintain(self, now: float) -> float:
        """Say HELLO when due; return when this must run again."""
        if self._working(now):
            if self._join_at is not None:
                return self._join_at + JOIN_WAIT_S
            assert self._last_sample_at is not None
            return self._last_sample_at + REJOIN_S
        if now - self._last_hello >= HELLO_INTERVAL_S:
            self._join_at = None
            self._send_hello(now)
        return self._last_hello + HELLO_INTERVAL_S

    def _send_hello(self, now: float) -> None:
        seq = self._next_host_seq()
        self._last_hello = now  # the attempt counts: no HELLO storm on send errors
        if self._hellos and now - self._hellos[-1][1] > HELLO_REDRAW_GAP_S:
            # The host was busy (the worker warming its controller after open()): the
            # device will likely redraw for this HELLO, and a JOIN to an earlier
            # CHALLENGE would be dropped as a replay, the join a JOIN_WAIT_S late.
            self._hellos.clear()
        while self._hellos and now - self._hellos[0][1] > HELLO_MEMORY_S:
            self._hellos.popleft()
        self._hellos.append((seq, now))
        if self._sendto(encode_hello(HelloPacket(host_seq=seq), self.key, self.session)):
            self.stats.hellos_sent += 1
        self._silent_hellos += 1
        if self._silent_hellos >= SILENT_HELLOS and not self.problem:
            ip, port = self._device_addr
            self.problem = (
                f"no version {VERSION} device answers at {ip}:{port} after "
                f"{self._silent_hellos} HELLOs: its firmware may be older than protocol "
                f"version {VERSION}, it may hold another link key (this host's key id is "
                f"{self.key_id}), or the address may be wrong")

    def _check_outage(self, now: float) -> None:
        last = self._last_sample_at
        if last is not None and not self._in_outage and now - last > OUTAGE_S:
            self._in_outage = True
            self.stats.outages += 1
            self._events.append(f"link outage: no sample for more than {1000 * OUTAGE_S:.0f} ms")

    def _on_version(self, packet: VersionPacket) -> None:
        self.stats.versions += 1
        if packet.lowest <= VERSION <= packet.highest:
            return  # a device that speaks ours too: nothing to report
        self.problem = (
            f"the device speaks protocol versions {packet.lowest}..{packet.highest}; this "
            f"host speaks {LOWEST_VERSION}..{VERSION}: update the "
            f"{'firmware' if packet.highest < VERSION else 'host'}; no controller runs "
            "on this link until then")

    def _on_challenge(self, packet: ChallengePacket, sender: int, receiver: int) -> None:
        now = time.monotonic()
        if receiver != self.session or seq_diff(packet.hello_seq, self._host_seq) > 0:
            self.stats.replayed += 1  # to another host session, or a HELLO never sent
            return
        recent = {seq for seq, at in self._hellos if now - at <= HELLO_MEMORY_S}
        if packet.hello_seq not in recent or (
                self._answered is not None and seq_diff(packet.hello_seq, self._answered) <= 0):
            # An answer to one of this session's own HELLOs that comes too late: the
            # HELLO is older than a second (the host was busy between open() and its
            # first read, or the path delayed it), or a JOIN already superseded it. The
            # device's own doing, or a copy of it: ignored, and not an attack.
            self.stats.late_challenges += 1
            return
        # One JOIN per join: every HELLO sent so far is answered by this JOIN. A second
        # CHALLENGE to one of them (the device answered two HELLOs that crossed the
        # first CHALLENGE, with the same challenge) would make a JOIN the device drops
        # as a replay of the spent challenge.
        self._answered = self._hellos[-1][0] if self._hellos else packet.hello_seq
        self._silent_hellos = 0
        self.problem = ""
        if self.device_session is not None and sender != self.device_session:
            self.stats.restarts += 1
            self._events.append("device restarted (new session); host sequence continues")
        if sender != self.device_session:
            self._last_wire = None  # the new boot numbers its samples from 0
        self.device_session = sender
        self._offered = DeviceIdentity(
            unique_id=packet.unique_id.hex(), firmware=packet.firmware, key_id=self.key_id,
            device_session=sender)
        join = JoinPacket(host_seq=self._next_host_seq(), challenge=packet.challenge)
        if self._sendto(encode_join(join, self.key, self.session, sender)):
            self.stats.joins += 1
        self._join_at = now

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
        if isinstance(packet, ChallengePacket):
            self._on_challenge(packet, frame.sender, frame.receiver)
            return None
        if isinstance(packet, VersionPacket):
            self._on_version(packet)
            return None
        if not isinstance(packet, Sample):
            self.stats.unexpected += 1
            return None
        if frame.receiver != self.session or frame.sender != self.device_session:
            # Authentic, but of another device boot or to another host session:
            # recorded and sent again (or left over from before a restart).
            self.stats.replayed += 1
            return None
        if self._last_wire is None:
            step = 1
        else:
            step = seq_diff(packet.seq, self._last_wire)
            if step == 0:
                self.stats.duplicates += 1
                return None
            if step < 0:
                self.stats.stale += 1  # reordered: a newer sample was already used
                return None
            if step > 1:
                self.stats.gaps += 1
                self.stats.missing += step - 1
        now = time.monotonic()
        self.stats.device_auth_drops = frame.device_auth_drops
        self.stats.device_replay_drops = frame.device_replay_drops
        self.stats.device_stale_drops = frame.device_stale_drops
        if self._in_outage and self._last_sample_at is not None:
            gap_ms = 1000 * (now - self._last_sample_at)
            self._events.append(f"link outage ended: samples resumed after {gap_ms:.0f} ms")
        if self._host_ext < 0 and self.stats.samples == 0:
            self._host_ext = packet.seq - 1  # the host sequence starts equal to the wire's
        self._in_outage = False
        self._last_sample_at = now
        self._join_at = None
        if self._offered is not None:
            self._identity = self._offered
        self._last_wire = packet.seq
        self._host_ext += step
        self.stats.samples += 1
        return replace(packet, seq=self._host_ext)
