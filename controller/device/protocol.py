"""The exoskeleton wire protocol: one definition of every packet, used by host and device.

The layout is specified for firmware engineers in `docs/device-protocol.md`; this module
is its executable form. Both the host (`UdpDevice`) and the simulated exoskeleton
(`controller.sim.device_server`) encode and decode through these functions only, so the
two sides cannot drift apart. Everything is little-endian and fixed-size except the
optional ground-truth extension of a sample.

Version 2 authenticates every packet (`controller.device.auth`): after the payload come
the sender's and the receiver's session numbers and an HMAC-SHA256 tag over all bytes
before it, in place of version 1's CRC-32. Encoding needs the key and the sessions;
decoding checks the tag before it reads anything else, and returns the packet with its
sessions (`Frame`) for the receiver's replay checks.
"""

from __future__ import annotations

import enum
import math
import struct
from dataclasses import dataclass

from controller.device.auth import TAG_BYTES, tag, verify
from controller.device.base import ENCODER_COUNTS, GroundTruth, LockCommand, Sample, Status

MAGIC = b"EX"
VERSION = 2
DEFAULT_PORT = 47_300  # the device's UDP port unless configured otherwise
SEQ_MODULUS = 1 << 32  # sequence numbers are uint32 and wrap
MAX_ACTIVITY_BYTES = 64

# Header: magic (2 bytes), version u8, type u8, payload length u16, flags u16.
HEADER = struct.Struct("<2sBBHH")
# Authentication trailer before the tag: sender's session u64, receiver's session u64.
SESSIONS = struct.Struct("<QQ")
TRAILER = SESSIONS.size + TAG_BYTES
# Sample payload: device time in microseconds u64, sequence u32, status u32, 4 counts u16,
# then the device's counts of commands it dropped: failed tag u32, replayed or stale u32.
SAMPLE_BODY = struct.Struct("<QII4HII")
# Ground-truth extension: progress f64, lift index i32, activity length u8 (+ UTF-8 bytes).
TRUTH_BODY = struct.Struct("<diB")
# Command payload: host sequence u32, echoed sample sequence u32, lock bits u8, 3 reserved.
COMMAND_BODY = struct.Struct("<IIB3x")
# Hello payload: host sequence u32, 4 reserved.
HELLO_BODY = struct.Struct("<I4x")

MIN_PACKET = HEADER.size + TRAILER
MAX_PACKET = HEADER.size + SAMPLE_BODY.size + TRUTH_BODY.size + MAX_ACTIVITY_BYTES + TRAILER
_U64 = 1 << 64
_U32 = 1 << 32

SAMPLE_HAS_TRUTH = 1 << 0  # sample flag: the ground-truth extension follows
COMMAND_ECHO_VALID = 1 << 0  # command flag: echo_seq names a sample the host received
LOCK_LEFT_BIT = 1 << 0
LOCK_RIGHT_BIT = 1 << 1

_KNOWN_STATUS = 0
for _bit in Status:
    _KNOWN_STATUS |= int(_bit)


class PacketType(enum.IntEnum):
    """The `type` byte of the header."""

    SAMPLE = 1  # device -> host, 100 Hz
    COMMAND = 2  # host -> device, once per sample
    HELLO = 3  # host -> device, registers the host's port; never feeds the watchdog


class ProtocolError(ValueError):
    """A packet that must be dropped. `reason` is a short tag used when counting drops."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True, slots=True)
class CommandPacket:
    """A host command as it travels: the lock bits plus the sequencing needed to drop
    stale commands and to measure the sample-to-command round trip."""

    host_seq: int
    lock_left: bool
    lock_right: bool
    echo_seq: int | None = None  # sequence of the last sample the host received

    def as_lock_command(self) -> LockCommand:
        """The device-side view: just the solenoid request."""
        return LockCommand(seq=self.host_seq, lock_left=self.lock_left, lock_right=self.lock_right)


@dataclass(frozen=True, slots=True)
class HelloPacket:
    """Host announcement: tells the device where to stream samples before any command."""

    host_seq: int


Packet = Sample | CommandPacket | HelloPacket


@dataclass(frozen=True, slots=True)
class Frame:
    """An authentic packet with what the receiver needs to judge its freshness: the
    sender's session, the receiver's session as the sender knows it (0: unknown), and,
    in a SAMPLE, the device's counts of commands it dropped."""

    packet: Packet
    sender: int
    receiver: int
    device_auth_drops: int = 0
    device_replay_drops: int = 0


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
    head = HEADER.pack(MAGIC, VERSION, int(ptype), len(payload), flags)
    body = head + payload + SESSIONS.pack(sender, receiver)
    return body + tag(key, body)


def _check_u32(name: str, value: int) -> int:
    if not 0 <= value < SEQ_MODULUS:
        raise ProtocolError("range", f"{name} {value} outside uint32")
    return value


def encode_sample(sample: Sample, key: bytes, sender: int, receiver: int,
                  auth_drops: int = 0, replay_drops: int = 0) -> bytes:
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
                               min(auth_drops, _U32 - 1), min(replay_drops, _U32 - 1))
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
    flags = 0 if packet.echo_seq is None else COMMAND_ECHO_VALID
    echo = 0 if packet.echo_seq is None else packet.echo_seq % SEQ_MODULUS
    payload = COMMAND_BODY.pack(_check_u32("host_seq", packet.host_seq), echo, bits)
    return _frame(PacketType.COMMAND, flags, payload, key, sender, receiver)


def encode_hello(packet: HelloPacket, key: bytes, sender: int, receiver: int = 0) -> bytes:
    """A HELLO packet from host session `sender` (`receiver`: the device's, if known)."""
    return _frame(PacketType.HELLO, 0, HELLO_BODY.pack(_check_u32("host_seq", packet.host_seq)),
                  key, sender, receiver)


def encode(packet: Packet, key: bytes, sender: int, receiver: int) -> bytes:
    """Any packet, dispatched on its Python type."""
    if isinstance(packet, Sample):
        return encode_sample(packet, key, sender, receiver)
    if isinstance(packet, CommandPacket):
        return encode_command(packet, key, sender, receiver)
    return encode_hello(packet, key, sender, receiver)


def _unframe(data: bytes, key: bytes) -> tuple[PacketType, int, bytes, int, int]:
    """Check everything that is the same for every packet type; return type, flags,
    payload and the two sessions.

    Order matters: the tag is checked before any field is believed, so a damaged or
    forged version byte is reported as "auth", and only authentic packets count as
    "version".
    """
    if len(data) < MIN_PACKET:
        raise ProtocolError("short", f"{len(data)} bytes, a packet has at least {MIN_PACKET}")
    magic, version, ptype, length, flags = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ProtocolError("magic", f"magic {magic!r}, expected {MAGIC!r}")
    if len(data) != HEADER.size + length + TRAILER:
        raise ProtocolError(
            "length", f"header says {length} payload bytes, datagram has {len(data) - MIN_PACKET}"
        )
    signed = len(data) - TAG_BYTES
    view = memoryview(data)
    if not verify(key, view[:signed], view[signed:]):
        raise ProtocolError("auth", "message authentication code does not match")
    if version != VERSION:
        raise ProtocolError("version", f"protocol version {version}, this side speaks {VERSION}")
    try:
        kind = PacketType(ptype)
    except ValueError:
        raise ProtocolError("type", f"unknown packet type {ptype}") from None
    sender, receiver = SESSIONS.unpack_from(data, signed - SESSIONS.size)
    return kind, flags, bytes(data[HEADER.size : signed - SESSIONS.size]), sender, receiver


def _expect_size(kind: PacketType, payload: bytes, size: int) -> None:
    if len(payload) != size:
        raise ProtocolError("length", f"{kind.name} payload is {len(payload)} bytes, not {size}")


def _decode_sample(flags: int, payload: bytes) -> tuple[Sample, int, int]:
    if flags & ~SAMPLE_HAS_TRUTH:
        raise ProtocolError("flags", f"unknown SAMPLE flags {flags:#x}")
    if len(payload) < SAMPLE_BODY.size:
        raise ProtocolError("length", f"SAMPLE payload is {len(payload)} bytes, too short")
    t_us, seq, status, *counts, auth_drops, replay_drops = SAMPLE_BODY.unpack_from(payload)
    for i, c in enumerate(counts):
        if c >= ENCODER_COUNTS:
            raise ProtocolError("counts", f"encoder {i} count {c} outside 0..{ENCODER_COUNTS - 1}")
    if status & ~_KNOWN_STATUS:
        raise ProtocolError("status", f"reserved status bits set: {status & ~_KNOWN_STATUS:#x}")
    truth = None
    if flags & SAMPLE_HAS_TRUTH:
        base = SAMPLE_BODY.size + TRUTH_BODY.size
        if len(payload) < base:
            raise ProtocolError("length", "SAMPLE truth extension is cut short")
        progress, lift, n = TRUTH_BODY.unpack_from(payload, SAMPLE_BODY.size)
        _expect_size(PacketType.SAMPLE, payload, base + n)
        try:
            activity = payload[base:].decode("utf-8")
        except UnicodeDecodeError:
            raise ProtocolError("truth", "activity name is not UTF-8") from None
        truth = GroundTruth(activity=activity, lift_index=lift, progress=progress)
    else:
        _expect_size(PacketType.SAMPLE, payload, SAMPLE_BODY.size)
    sample = Sample(
        seq=seq,
        t=t_us / 1e6,
        counts=(counts[0], counts[1], counts[2], counts[3]),
        status=Status(status),
        truth=truth,
    )
    return sample, auth_drops, replay_drops


def _decode_command(flags: int, payload: bytes) -> CommandPacket:
    if flags & ~COMMAND_ECHO_VALID:
        raise ProtocolError("flags", f"unknown COMMAND flags {flags:#x}")
    _expect_size(PacketType.COMMAND, payload, COMMAND_BODY.size)
    if payload[9:12] != b"\0\0\0":
        raise ProtocolError("reserved", "COMMAND reserved bytes are not zero")
    host_seq, echo, bits = COMMAND_BODY.unpack(payload)
    if bits & ~(LOCK_LEFT_BIT | LOCK_RIGHT_BIT):
        raise ProtocolError("reserved", f"unknown lock bits {bits:#x}")
    return CommandPacket(
        host_seq=host_seq,
        lock_left=bool(bits & LOCK_LEFT_BIT),
        lock_right=bool(bits & LOCK_RIGHT_BIT),
        echo_seq=echo if flags & COMMAND_ECHO_VALID else None,
    )


def _decode_hello(flags: int, payload: bytes) -> HelloPacket:
    if flags:
        raise ProtocolError("flags", f"unknown HELLO flags {flags:#x}")
    _expect_size(PacketType.HELLO, payload, HELLO_BODY.size)
    if payload[4:8] != b"\0\0\0\0":
        raise ProtocolError("reserved", "HELLO reserved bytes are not zero")
    (host_seq,) = HELLO_BODY.unpack(payload)
    return HelloPacket(host_seq=host_seq)


def decode_frame(data: bytes, key: bytes) -> Frame:
    """Any authentic packet with its sessions. Raises `ProtocolError` for anything
    malformed or not authentic; never returns partial data."""
    kind, flags, payload, sender, receiver = _unframe(data, key)
    if kind is PacketType.SAMPLE:
        sample, auth_drops, replay_drops = _decode_sample(flags, payload)
        return Frame(sample, sender, receiver, auth_drops, replay_drops)
    if kind is PacketType.COMMAND:
        return Frame(_decode_command(flags, payload), sender, receiver)
    return Frame(_decode_hello(flags, payload), sender, receiver)


def decode(data: bytes, key: bytes) -> Packet:
    """Any authentic packet, without its sessions (see `decode_frame`)."""
    return decode_frame(data, key).packet


def decode_sample(data: bytes, key: bytes) -> Sample:
    """A SAMPLE packet; any other type is a `ProtocolError` ("type")."""
    packet = decode(data, key)
    if not isinstance(packet, Sample):
        raise ProtocolError("type", f"expected SAMPLE, got {type(packet).__name__}")
    return packet


def decode_command(data: bytes, key: bytes) -> CommandPacket:
    """A COMMAND packet; any other type is a `ProtocolError` ("type")."""
    packet = decode(data, key)
    if not isinstance(packet, CommandPacket):
        raise ProtocolError("type", f"expected COMMAND, got {type(packet).__name__}")
    return packet
