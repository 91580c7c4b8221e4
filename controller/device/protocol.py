"""The exoskeleton wire protocol: one definition of every packet, used by host and device.

The layout is specified for firmware engineers in `docs/device-protocol.md`; this module
is its executable form. Both the host (`UdpDevice`) and the simulated exoskeleton
(`controller.sim.device_server`) encode and decode through these functions only, so the
two sides cannot drift apart. Everything is little-endian and fixed-size except the
optional ground-truth extension of a sample.
"""

from __future__ import annotations

import enum
import math
import struct
import zlib
from dataclasses import dataclass

from controller.device.base import ENCODER_COUNTS, GroundTruth, LockCommand, Sample, Status

MAGIC = b"EX"
VERSION = 1
DEFAULT_PORT = 47_300  # the device's UDP port unless configured otherwise
SEQ_MODULUS = 1 << 32  # sequence numbers are uint32 and wrap
MAX_ACTIVITY_BYTES = 64

# Header: magic (2 bytes), version u8, type u8, payload length u16, flags u16.
HEADER = struct.Struct("<2sBBHH")
CRC = struct.Struct("<I")
# Sample payload: device time in microseconds u64, sequence u32, status u32, 4 counts u16.
SAMPLE_BODY = struct.Struct("<QII4H")
# Ground-truth extension: progress f64, lift index i32, activity length u8 (+ UTF-8 bytes).
TRUTH_BODY = struct.Struct("<diB")
# Command payload: host sequence u32, echoed sample sequence u32, lock bits u8, 3 reserved.
COMMAND_BODY = struct.Struct("<IIB3x")
# Hello payload: host sequence u32, 4 reserved.
HELLO_BODY = struct.Struct("<I4x")

MIN_PACKET = HEADER.size + CRC.size
MAX_PACKET = HEADER.size + SAMPLE_BODY.size + TRUTH_BODY.size + MAX_ACTIVITY_BYTES + CRC.size

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


def seq_diff(new: int, old: int) -> int:
    """Signed distance from `old` to `new` in uint32 serial arithmetic (RFC 1982):
    positive when `new` is later, negative when it is earlier, also across the wrap."""
    d = (new - old) % SEQ_MODULUS
    return d - SEQ_MODULUS if d >= SEQ_MODULUS // 2 else d


def _frame(ptype: PacketType, flags: int, payload: bytes) -> bytes:
    head = HEADER.pack(MAGIC, VERSION, int(ptype), len(payload), flags)
    body = head + payload
    return body + CRC.pack(zlib.crc32(body))


def _check_u32(name: str, value: int) -> int:
    if not 0 <= value < SEQ_MODULUS:
        raise ProtocolError("range", f"{name} {value} outside uint32")
    return value


def encode_sample(sample: Sample) -> bytes:
    """A SAMPLE packet. The sequence is sent modulo 2**32 (hosts extend it again);
    the time is rounded to whole microseconds."""
    for i, c in enumerate(sample.counts):
        if not 0 <= c < ENCODER_COUNTS:
            raise ProtocolError("counts", f"encoder {i} count {c} outside 0..{ENCODER_COUNTS - 1}")
    if not (math.isfinite(sample.t) and sample.t >= 0.0):
        raise ProtocolError("time", f"device time {sample.t} is not a finite non-negative value")
    status = int(sample.status)
    if status & ~_KNOWN_STATUS:
        raise ProtocolError("status", f"unknown status bits {status & ~_KNOWN_STATUS:#x}")
    t_us = round(sample.t * 1e6)
    payload = SAMPLE_BODY.pack(t_us, sample.seq % SEQ_MODULUS, status, *sample.counts)
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
    return _frame(PacketType.SAMPLE, flags, payload)


def encode_command(packet: CommandPacket) -> bytes:
    """A COMMAND packet."""
    bits = (LOCK_LEFT_BIT if packet.lock_left else 0) | (LOCK_RIGHT_BIT if packet.lock_right else 0)
    flags = 0 if packet.echo_seq is None else COMMAND_ECHO_VALID
    echo = 0 if packet.echo_seq is None else packet.echo_seq % SEQ_MODULUS
    payload = COMMAND_BODY.pack(_check_u32("host_seq", packet.host_seq), echo, bits)
    return _frame(PacketType.COMMAND, flags, payload)


def encode_hello(packet: HelloPacket) -> bytes:
    """A HELLO packet."""
    return _frame(PacketType.HELLO, 0, HELLO_BODY.pack(_check_u32("host_seq", packet.host_seq)))


def encode(packet: Packet) -> bytes:
    """Any packet, dispatched on its Python type."""
    if isinstance(packet, Sample):
        return encode_sample(packet)
    if isinstance(packet, CommandPacket):
        return encode_command(packet)
    return encode_hello(packet)


def _unframe(data: bytes) -> tuple[PacketType, int, bytes]:
    """Check everything that is the same for every packet type; return type, flags, payload.

    Order matters: the header and CRC layout are version-independent, so a corrupted
    version byte is reported as a CRC error, and only intact packets count as "version".
    """
    if len(data) < MIN_PACKET:
        raise ProtocolError("short", f"{len(data)} bytes, a packet has at least {MIN_PACKET}")
    magic, version, ptype, length, flags = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ProtocolError("magic", f"magic {magic!r}, expected {MAGIC!r}")
    if len(data) != HEADER.size + length + CRC.size:
        raise ProtocolError(
            "length", f"header says {length} payload bytes, datagram has {len(data) - MIN_PACKET}"
        )
    (crc,) = CRC.unpack_from(data, len(data) - CRC.size)
    actual = zlib.crc32(memoryview(data)[: len(data) - CRC.size])
    if crc != actual:
        raise ProtocolError("crc", f"CRC {crc:#010x}, computed {actual:#010x}")
    if version != VERSION:
        raise ProtocolError("version", f"protocol version {version}, this side speaks {VERSION}")
    try:
        kind = PacketType(ptype)
    except ValueError:
        raise ProtocolError("type", f"unknown packet type {ptype}") from None
    return kind, flags, bytes(data[HEADER.size : len(data) - CRC.size])


def _expect_size(kind: PacketType, payload: bytes, size: int) -> None:
    if len(payload) != size:
        raise ProtocolError("length", f"{kind.name} payload is {len(payload)} bytes, not {size}")


def _decode_sample(flags: int, payload: bytes) -> Sample:
    if flags & ~SAMPLE_HAS_TRUTH:
        raise ProtocolError("flags", f"unknown SAMPLE flags {flags:#x}")
    if len(payload) < SAMPLE_BODY.size:
        raise ProtocolError("length", f"SAMPLE payload is {len(payload)} bytes, too short")
    t_us, seq, status, *counts = SAMPLE_BODY.unpack_from(payload)
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
    return Sample(
        seq=seq,
        t=t_us / 1e6,
        counts=(counts[0], counts[1], counts[2], counts[3]),
        status=Status(status),
        truth=truth,
    )


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


def decode(data: bytes) -> Packet:
    """Any packet. Raises `ProtocolError` for anything malformed; never returns partial data."""
    kind, flags, payload = _unframe(data)
    if kind is PacketType.SAMPLE:
        return _decode_sample(flags, payload)
    if kind is PacketType.COMMAND:
        return _decode_command(flags, payload)
    return _decode_hello(flags, payload)


def decode_sample(data: bytes) -> Sample:
    """A SAMPLE packet; any other type is a `ProtocolError` ("type")."""
    packet = decode(data)
    if not isinstance(packet, Sample):
        raise ProtocolError("type", f"expected SAMPLE, got {type(packet).__name__}")
    return packet


def decode_command(data: bytes) -> CommandPacket:
    """A COMMAND packet; any other type is a `ProtocolError` ("type")."""
    packet = decode(data)
    if not isinstance(packet, CommandPacket):
        raise ProtocolError("type", f"expected COMMAND, got {type(packet).__name__}")
    return packet
