"""The exoskeleton wire protocol: one definition of every packet, used by host and device.

The layout is specified for firmware engineers in `docs/device-protocol.md`; this module
is its executable form. Both the host (`UdpDevice`) and the simulated exoskeleton
(`controller.sim.device_server`) encode and decode through these functions only, so the
two sides cannot drift apart. Everything is little-endian and fixed-size except the
optional ground-truth extension of a sample.

Every packet ends with an HMAC-SHA256 tag (`controller.device.auth`) over all bytes
before it; every packet but VERSION carries the sender's and the receiver's session
numbers before the tag. Decoding checks the tag before it believes any field, then
validates in the documented order, so that the first failure names the drop reason the
C core names too. Version 3 adds the join handshake (HELLO -> CHALLENGE -> JOIN), the
device's count of stale commands, the heartbeat probe flag and status bits, and the
VERSION packet whose layout never changes, so that peers of different versions can say
so instead of staying silent.
"""

from __future__ import annotations

import enum
import math
import struct
from dataclasses import dataclass

from controller.device.auth import TAG_BYTES, tag, verify
from controller.device.base import ENCODER_COUNTS, GroundTruth, LockCommand, Sample, Status

MAGIC = b"EX"
VERSION = 3
LOWEST_VERSION = 3  # the oldest version this side speaks (sent in VERSION packets)
DEFAULT_PORT = 47_300  # the device's UDP port unless configured otherwise
SEQ_MODULUS = 1 << 32  # sequence numbers are uint32 and wrap
MAX_ACTIVITY_BYTES = 64
CHALLENGE_BYTES = 16
UNIQUE_ID_BYTES = 16
FIRMWARE_BYTES = 16
CHALLENGE_LIFETIME_MS = 1000  # what a CHALLENGE says, and what the device enforces
#: A HELLO draws a new challenge when the current one is older than this (or spent): the
#: earlier challenge is then dead, so the host must not answer a CHALLENGE it got before.
CHALLENGE_REDRAW_MS = 500
#: The device's command watchdog: the solenoids go off this long after the sample the
#: last command it took answered (on the device's clock). No release can come sooner.
WATCHDOG_S = 0.100

# Header: magic (2 bytes), version u8, type u8, payload length u16, flags u16.
HEADER = struct.Struct("<2sBBHH")
# Authentication trailer before the tag: sender's session u64, receiver's session u64.
SESSIONS = struct.Struct("<QQ")
TRAILER = SESSIONS.size + TAG_BYTES
# Sample payload: device time in microseconds u64, sequence u32, status u32, 4 counts u16,
# then the device's counts of datagrams it dropped: failed tag, replayed, stale (u32 each).
SAMPLE_BODY = struct.Struct("<QII4HIII")
# Ground-truth extension: progress f64, lift index i32, activity length u8 (+ UTF-8 bytes).
TRUTH_BODY = struct.Struct("<diB")
# Command payload: host sequence u32, echoed sample sequence u32, lock bits u8, 3 reserved.
COMMAND_BODY = struct.Struct("<IIB3x")
# Hello payload: host sequence u32, 4 reserved.
HELLO_BODY = struct.Struct("<I4x")
# Challenge payload: hello_seq u32, lifetime_ms u32, challenge, unique id, firmware.
CHALLENGE_BODY = struct.Struct(f"<II{CHALLENGE_BYTES}s{UNIQUE_ID_BYTES}s{FIRMWARE_BYTES}s")
# Join payload: host sequence u32, 4 reserved, the challenge copied back.
JOIN_BODY = struct.Struct(f"<I4x{CHALLENGE_BYTES}s")
# Version payload (frozen in every version): lowest u8, highest u8, reserved u16.
VERSION_BODY = struct.Struct("<BBH")

VERSION_PACKET = HEADER.size + VERSION_BODY.size + TAG_BYTES  # 44: the smallest packet
MIN_PACKET = VERSION_PACKET
MAX_PACKET = HEADER.size + SAMPLE_BODY.size + TRUTH_BODY.size + MAX_ACTIVITY_BYTES + TRAILER
_U64 = 1 << 64
_U32 = 1 << 32

SAMPLE_HAS_TRUTH = 1 << 0  # sample flag: the ground-truth extension follows
COMMAND_STOP_HEARTBEAT = 1 << 0  # command flag: stop toggling the heartbeat output
LOCK_LEFT_BIT = 1 << 0
LOCK_RIGHT_BIT = 1 << 1

_KNOWN_STATUS = 0
for _bit in Status:
    _KNOWN_STATUS |= int(_bit)


class PacketType(enum.IntEnum):
    """The `type` byte of the header."""

    SAMPLE = 1  # device -> host, 100 Hz
    COMMAND = 2  # host -> device, once per sample
    HELLO = 3  # host -> device, asks for a challenge; changes nothing else
    CHALLENGE = 4  # device -> host, answers a HELLO
    JOIN = 5  # host -> device, answers a CHALLENGE: opens the host's session
    VERSION = 6  # device -> host, "I speak versions L..H" (frozen layout)


#: Every drop reason, validation first (in the order of the document's table, where
#: `length` appears twice), then the receivers' state checks. The C core uses the same
#: names (firmware/core), so statistics of the two devices compare key by key.
VALIDATION_REASONS = ("short", "magic", "length", "auth", "version", "type", "flags",
                      "counts", "status", "reserved", "truth", "identity")
STATE_REASONS = ("foreign", "flood", "replay", "stale_echo", "unexpected")


class ProtocolError(ValueError):
    """A packet that must be dropped. `reason` is a short tag used when counting drops."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True, slots=True)
class CommandPacket:
    """A host command as it travels: the lock bits, the heartbeat probe flag, and the
    sequencing the device judges it by (`echo_seq`: the sample it answers)."""

    host_seq: int
    lock_left: bool
    lock_right: bool
    echo_seq: int
    stop_heartbeat: bool = False

    def as_lock_command(self) -> LockCommand:
        """The device-side view: just the solenoid request."""
        return LockCommand(seq=self.host_seq, lock_left=self.lock_left,
                           lock_right=self.lock_right, stop_heartbeat=self.stop_heartbeat)


@dataclass(frozen=True, slots=True)
class HelloPacket:
    """Host request for a challenge; it opens, moves and changes nothing."""

    host_seq: int


@dataclass(frozen=True, slots=True)
class ChallengePacket:
    """The device's answer to a HELLO: a single-use challenge and its identity."""

    hello_seq: int
    challenge: bytes
    unique_id: bytes
    firmware: str
    lifetime_ms: int = CHALLENGE_LIFETIME_MS


@dataclass(frozen=True, slots=True)
class JoinPacket:
    """The host's answer to a CHALLENGE: fresh proof of the key, opens its session."""

    host_seq: int
    challenge: bytes


@dataclass(frozen=True, slots=True)
class VersionPacket:
    """The protocol versions the sender speaks (the one layout every version reads)."""

    lowest: int
    highest: int


Packet = Sample | CommandPacket | HelloPacket | ChallengePacket | JoinPacket | VersionPacket


@dataclass(frozen=True, slots=True)
class Frame:
    """An authentic packet with what the receiver needs to judge its freshness: the
    sender's session, the receiver's session as the sender knows it (both 0 in a
    VERSION packet, which has none), and, in a SAMPLE, the device's drop counts."""

    packet: Packet
    sender: int
    receiver: int
    device_auth_drops: int = 0
    device_replay_drops: int = 0
    device_stale_drops: int = 0


def seq_diff(new: int, old: int) -> int:
    """Signed distance from `old` to `new` in uint32 serial arithmetic (RFC 1982):
    positive when `new` is later, negative when it is earlier, also across the wrap."""
    d = (new - old) % SEQ_MODULUS
    return d - SEQ_MODULUS if d >= SEQ_MODULUS // 2 else d


def _frame(ptype: PacketType, flags: int, payload: bytes, key: bytes, sender: int,
           receiver: int) -> bytes:
    for name, v in (("sender session", sender), ("receiver session", receiver)):
        if not 0 <= v < _U64:
            raise ProtocolError("range", f"{name} {v} outside uint64")
    if sender == 0:
        raise ProtocolError("reserved", "a sender session is never 0")
    head = HEADER.pack(MAGIC, VERSION, int(ptype), len(payload), flags)
    body = head + payload + SESSIONS.pack(sender, receiver)
    return body + tag(key, body)


def _check_u32(name: str, value: int) -> int:
    if not 0 <= value < SEQ_MODULUS:
        raise ProtocolError("range", f"{name} {value} outside uint32")
    return value


def _check_bytes(name: str, value: bytes, size: int) -> bytes:
    if len(value) != size:
        raise ProtocolError("range", f"{name} is {len(value)} bytes, not {size}")
    return value


def encode_sample(sample: Sample, key: bytes, sender: int, receiver: int,
                  auth_drops: int = 0, replay_drops: int = 0, stale_drops: int = 0) -> bytes:
    """A SAMPLE packet from device session `sender` to host session `receiver`. The
    sequence is sent modulo 2**32 (hosts extend it again); the time is rounded to whole
    microseconds; the drop counts saturate at 2**32 - 1."""
    for i, c in enumerate(sample.counts):
        if not 0 <= c < ENCODER_COUNTS:
            raise ProtocolError("counts", f"encoder {i} count {c} outside 0..{ENCODER_COUNTS - 1}")
    if not (math.isfinite(sample.t) and sample.t >= 0.0):
        raise ProtocolError("time", f"device time {sample.t} is not a finite non-negative value")
    status = int(sample.status)
    if status & ~_KNOWN_STATUS:
        raise ProtocolError("status", f"unknown status bits {status & ~_KNOWN_STATUS:#x}")
    t_us = round(sample.t * 1e6)
    payload = SAMPLE_BODY.pack(t_us, sample.seq % SEQ_MODULUS, status, *sample.counts,
                               min(auth_drops, _U32 - 1), min(replay_drops, _U32 - 1),
                               min(stale_drops, _U32 - 1))
    flags = 0
    if sample.truth is not None:
        name = sample.truth.activity.encode("utf-8")
        if len(name) > MAX_ACTIVITY_BYTES:
            raise ProtocolError("truth", f"activity name longer than {MAX_ACTIVITY_BYTES} bytes")
        if not -(1 << 31) <= sample.truth.lift_index < (1 << 31):
            raise ProtocolError("truth", f"lift index {sample.truth.lift_index} outside int32")
        payload += TRUTH_BODY.pack(sample.truth.progress, sample.truth.lift_index, len(name))
        payload += name
        flags |= SAMPLE_HAS_TRUTH
    return _frame(PacketType.SAMPLE, flags, payload, key, sender, receiver)


def encode_command(packet: CommandPacket, key: bytes, sender: int, receiver: int) -> bytes:
    """A COMMAND packet from host session `sender` to device session `receiver`."""
    bits = (LOCK_LEFT_BIT if packet.lock_left else 0) | (LOCK_RIGHT_BIT if packet.lock_right else 0)
    flags = COMMAND_STOP_HEARTBEAT if packet.stop_heartbeat else 0
    payload = COMMAND_BODY.pack(_check_u32("host_seq", packet.host_seq),
                                packet.echo_seq % SEQ_MODULUS, bits)
    return _frame(PacketType.COMMAND, flags, payload, key, sender, receiver)


def encode_hello(packet: HelloPacket, key: bytes, sender: int) -> bytes:
    """A HELLO packet from host session `sender` (its receiver session is always 0)."""
    return _frame(PacketType.HELLO, 0, HELLO_BODY.pack(_check_u32("host_seq", packet.host_seq)),
                  key, sender, 0)


def _firmware_field(text: str) -> bytes:
    raw = text.encode("ascii", errors="replace")
    if not 1 <= len(raw) <= FIRMWARE_BYTES or not all(0x20 <= b <= 0x7E for b in raw):
        raise ProtocolError("identity", f"firmware {text!r} is not 1..{FIRMWARE_BYTES} "
                            "printable ASCII characters")
    return raw.ljust(FIRMWARE_BYTES, b"\0")


def encode_challenge(packet: ChallengePacket, key: bytes, sender: int, receiver: int) -> bytes:
    """A CHALLENGE packet from device session `sender` to the HELLO's host session."""
    payload = CHALLENGE_BODY.pack(
        _check_u32("hello_seq", packet.hello_seq), _check_u32("lifetime_ms", packet.lifetime_ms),
        _check_bytes("challenge", packet.challenge, CHALLENGE_BYTES),
        _check_bytes("unique_id", packet.unique_id, UNIQUE_ID_BYTES),
        _firmware_field(packet.firmware))
    return _frame(PacketType.CHALLENGE, 0, payload, key, sender, receiver)


def encode_join(packet: JoinPacket, key: bytes, sender: int, receiver: int) -> bytes:
    """A JOIN packet from host session `sender` to device session `receiver`."""
    payload = JOIN_BODY.pack(_check_u32("host_seq", packet.host_seq),
                             _check_bytes("challenge", packet.challenge, CHALLENGE_BYTES))
    return _frame(PacketType.JOIN, 0, payload, key, sender, receiver)


def encode_version(packet: VersionPacket, key: bytes) -> bytes:
    """A VERSION packet (no sessions: its layout is the same in every version)."""
    if not 0 <= packet.lowest <= packet.highest <= 255:
        raise ProtocolError("reserved", f"versions {packet.lowest}..{packet.highest}")
    body = HEADER.pack(MAGIC, packet.highest, int(PacketType.VERSION), VERSION_BODY.size, 0)
    body += VERSION_BODY.pack(packet.lowest, packet.highest, 0)
    return body + tag(key, body)


def encode(packet: Packet, key: bytes, sender: int, receiver: int) -> bytes:
    """Any packet, dispatched on its Python type (a HELLO ignores `receiver`, a VERSION
    both sessions)."""
    if isinstance(packet, Sample):
        return encode_sample(packet, key, sender, receiver)
    if isinstance(packet, CommandPacket):
        return encode_command(packet, key, sender, receiver)
    if isinstance(packet, HelloPacket):
        return encode_hello(packet, key, sender)
    if isinstance(packet, ChallengePacket):
        return encode_challenge(packet, key, sender, receiver)
    if isinstance(packet, JoinPacket):
        return encode_join(packet, key, sender, receiver)
    return encode_version(packet, key)


def _unframe(data: bytes, key: bytes) -> tuple[PacketType, int, bytes, int, int]:
    """Check everything that is the same for every packet type; return type, flags,
    payload and the two sessions (0, 0 for VERSION).

    Order matters: the tag is checked before any field is believed, so a damaged or
    forged version byte is reported as "auth", and only authentic packets count as
    "version".
    """
    if len(data) < MIN_PACKET:
        raise ProtocolError("short", f"{len(data)} bytes, a packet has at least {MIN_PACKET}")
    magic, version, ptype, length, flags = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ProtocolError("magic", f"magic {magic!r}, expected {MAGIC!r}")
    trailer = TAG_BYTES if ptype == PacketType.VERSION else TRAILER
    if len(data) != HEADER.size + length + trailer:
        raise ProtocolError(
            "length", f"header says {length} payload bytes, datagram has "
            f"{len(data) - HEADER.size - trailer}")
    signed = len(data) - TAG_BYTES
    view = memoryview(data)
    if not verify(key, view[:signed], view[signed:]):
        raise ProtocolError("auth", "message authentication code does not match")
    if version != VERSION and ptype != PacketType.VERSION:
        raise ProtocolError("version", f"protocol version {version}, this side speaks {VERSION}")
    try:
        kind = PacketType(ptype)
    except ValueError:
        raise ProtocolError("type", f"unknown packet type {ptype}") from None
    if kind is PacketType.VERSION:
        return kind, flags, bytes(data[HEADER.size : signed]), 0, 0
    sender, receiver = SESSIONS.unpack_from(data, signed - SESSIONS.size)
    return kind, flags, bytes(data[HEADER.size : signed - SESSIONS.size]), sender, receiver


def _no_flags(kind: PacketType, flags: int) -> None:
    if flags:
        raise ProtocolError("flags", f"unknown {kind.name} flags {flags:#x}")


def _expect_size(kind: PacketType, payload: bytes, size: int) -> None:
    if len(payload) != size:
        raise ProtocolError("length", f"{kind.name} payload is {len(payload)} bytes, not {size}")


def _zero(kind: PacketType, payload: bytes, start: int, end: int) -> None:
    if any(payload[start:end]):
        raise ProtocolError("reserved", f"{kind.name} reserved bytes are not zero")


def _sender(kind: PacketType, sender: int) -> None:
    """Part of the `reserved` step: a session number is never 0 in a sender field."""
    if sender == 0:
        raise ProtocolError("reserved", f"{kind.name} with sender session 0")


def _decode_sample(flags: int, payload: bytes, sender: int) -> tuple[Sample, int, int, int]:
    if flags & ~SAMPLE_HAS_TRUTH:
        raise ProtocolError("flags", f"unknown SAMPLE flags {flags:#x}")
    if flags & SAMPLE_HAS_TRUTH:
        base = SAMPLE_BODY.size + TRUTH_BODY.size
        if len(payload) < base:
            raise ProtocolError("length", "SAMPLE truth extension is cut short")
        n = payload[base - 1]
        _expect_size(PacketType.SAMPLE, payload, base + n)
    else:
        _expect_size(PacketType.SAMPLE, payload, SAMPLE_BODY.size)
    t_us, seq, status, *rest = SAMPLE_BODY.unpack_from(payload)
    counts, (auth_drops, replay_drops, stale_drops) = rest[:4], rest[4:]
    for i, c in enumerate(counts):
        if c >= ENCODER_COUNTS:
            raise ProtocolError("counts", f"encoder {i} count {c} outside 0..{ENCODER_COUNTS - 1}")
    if status & ~_KNOWN_STATUS:
        raise ProtocolError("status", f"reserved status bits set: {status & ~_KNOWN_STATUS:#x}")
    _sender(PacketType.SAMPLE, sender)
    truth = None
    if flags & SAMPLE_HAS_TRUTH:
        progress, lift, _ = TRUTH_BODY.unpack_from(payload, SAMPLE_BODY.size)
        try:
            activity = payload[SAMPLE_BODY.size + TRUTH_BODY.size :].decode("utf-8")
        except UnicodeDecodeError:
            raise ProtocolError("truth", "activity name is not UTF-8") from None
        truth = GroundTruth(activity=activity, lift_index=lift, progress=progress)
    sample = Sample(
        seq=seq,
        t=t_us / 1e6,
        counts=(counts[0], counts[1], counts[2], counts[3]),
        status=Status(status),
        truth=truth,
    )
    return sample, auth_drops, replay_drops, stale_drops


def _decode_command(flags: int, payload: bytes, sender: int) -> CommandPacket:
    if flags & ~COMMAND_STOP_HEARTBEAT:
        raise ProtocolError("flags", f"unknown COMMAND flags {flags:#x}")
    _expect_size(PacketType.COMMAND, payload, COMMAND_BODY.size)
    host_seq, echo, bits = COMMAND_BODY.unpack(payload)
    if bits & ~(LOCK_LEFT_BIT | LOCK_RIGHT_BIT):
        raise ProtocolError("reserved", f"unknown lock bits {bits:#x}")
    _zero(PacketType.COMMAND, payload, 9, 12)
    _sender(PacketType.COMMAND, sender)
    return CommandPacket(
        host_seq=host_seq,
        lock_left=bool(bits & LOCK_LEFT_BIT),
        lock_right=bool(bits & LOCK_RIGHT_BIT),
        echo_seq=echo,
        stop_heartbeat=bool(flags & COMMAND_STOP_HEARTBEAT),
    )


def _decode_hello(flags: int, payload: bytes, sender: int, receiver: int) -> HelloPacket:
    _no_flags(PacketType.HELLO, flags)
    _expect_size(PacketType.HELLO, payload, HELLO_BODY.size)
    _zero(PacketType.HELLO, payload, 4, 8)
    if receiver != 0:
        raise ProtocolError("reserved", "a HELLO names receiver session 0, always")
    _sender(PacketType.HELLO, sender)
    (host_seq,) = HELLO_BODY.unpack(payload)
    return HelloPacket(host_seq=host_seq)


def _decode_challenge(flags: int, payload: bytes, sender: int) -> ChallengePacket:
    _no_flags(PacketType.CHALLENGE, flags)
    _expect_size(PacketType.CHALLENGE, payload, CHALLENGE_BODY.size)
    _sender(PacketType.CHALLENGE, sender)
    hello_seq, lifetime, challenge, unique_id, firmware = CHALLENGE_BODY.unpack(payload)
    text = firmware.rstrip(b"\0")
    if not text or b"\0" in text or not all(0x20 <= b <= 0x7E for b in text):
        raise ProtocolError("identity", "CHALLENGE firmware field is not printable ASCII, "
                            "NUL-padded and non-empty")
    return ChallengePacket(hello_seq=hello_seq, challenge=challenge, unique_id=unique_id,
                           firmware=text.decode("ascii"), lifetime_ms=lifetime)


def _decode_join(flags: int, payload: bytes, sender: int) -> JoinPacket:
    _no_flags(PacketType.JOIN, flags)
    _expect_size(PacketType.JOIN, payload, JOIN_BODY.size)
    _zero(PacketType.JOIN, payload, 4, 8)
    _sender(PacketType.JOIN, sender)
    host_seq, challenge = JOIN_BODY.unpack(payload)
    return JoinPacket(host_seq=host_seq, challenge=challenge)


def _decode_version(flags: int, payload: bytes) -> VersionPacket:
    _no_flags(PacketType.VERSION, flags)
    _expect_size(PacketType.VERSION, payload, VERSION_BODY.size)
    lowest, highest, reserved = VERSION_BODY.unpack(payload)
    if reserved or lowest > highest:
        raise ProtocolError("reserved", f"VERSION says {lowest}..{highest}, reserved {reserved}")
    return VersionPacket(lowest=lowest, highest=highest)


def decode_frame(data: bytes, key: bytes) -> Frame:
    """Any authentic packet with its sessions. Raises `ProtocolError` for anything
    malformed or not authentic; never returns partial data."""
    kind, flags, payload, sender, receiver = _unframe(data, key)
    if kind is PacketType.VERSION:
        return Frame(_decode_version(flags, payload), 0, 0)
    packet: Packet
    stale = replay = auth = 0
    if kind is PacketType.SAMPLE:
        packet, auth, replay, stale = _decode_sample(flags, payload, sender)
    elif kind is PacketType.COMMAND:
        packet = _decode_command(flags, payload, sender)
    elif kind is PacketType.HELLO:
        packet = _decode_hello(flags, payload, sender, receiver)
    elif kind is PacketType.CHALLENGE:
        packet = _decode_challenge(flags, payload, sender)
    else:
        packet = _decode_join(flags, payload, sender)
    return Frame(packet, sender, receiver, auth, replay, stale)


def decode(data: bytes, key: bytes) -> Packet:
    """Any authentic packet, without its sessions (see `decode_frame`)."""
    return decode_frame(data, key).packet


def decode_sample(data: bytes, key: bytes) -> Sample:
    """A SAMPLE packet; any other type is a `ProtocolError` ("unexpected")."""
    packet = decode(data, key)
    if not isinstance(packet, Sample):
        raise ProtocolError("unexpected", f"expected SAMPLE, got {type(packet).__name__}")
    return packet


def decode_command(data: bytes, key: bytes) -> CommandPacket:
    """A COMMAND packet; any other type is a `ProtocolError` ("unexpected")."""
    packet = decode(data, key)
    if not isinstance(packet, CommandPacket):
        raise ProtocolError("unexpected", f"expected COMMAND, got {type(packet).__name__}")
    return packet
