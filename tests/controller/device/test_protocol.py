"""The wire format: exact bytes, round trips, and every way a packet can be rejected."""

from __future__ import annotations

import math
import struct
import zlib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from controller.device.base import GroundTruth, Sample, Status
from controller.device.protocol import (
    CRC,
    HEADER,
    MAX_ACTIVITY_BYTES,
    CommandPacket,
    HelloPacket,
    ProtocolError,
    decode,
    decode_command,
    decode_sample,
    encode,
    encode_command,
    encode_hello,
    encode_sample,
    seq_diff,
)

# The example packets printed in docs/device-protocol.md; firmware tests use the same bytes.
DOC_SAMPLE = Sample(
    seq=258,
    t=2.58,
    counts=(3100, 3105, 12900, 12890),
    status=Status.SOLENOID_LEFT | Status.LOCKED_LEFT,
)
DOC_SAMPLE_HEX = (
    "45 58 01 01 18 00 00 00 20 5e 27 00 00 00 00 00 02 01 00 00 05 00 00 00 "
    "1c 0c 21 0c 64 32 5a 32 f3 b4 ce 91"
)
DOC_TRUTH_HEX = (
    "45 58 01 01 2a 00 01 00 20 5e 27 00 00 00 00 00 02 01 00 00 05 00 00 00 "
    "1c 0c 21 0c 64 32 5a 32 00 00 00 00 00 00 e0 3f 03 00 00 00 05 73 71 75 61 74 "
    "ba 19 63 1a"
)
DOC_COMMAND_HEX = "45 58 01 02 0c 00 01 00 07 00 00 00 02 01 00 00 01 00 00 00 98 b7 79 6f"
DOC_HELLO_HEX = "45 58 01 03 08 00 00 00 01 00 00 00 00 00 00 00 d4 b3 ef 13"


def _reframe(body: bytes) -> bytes:
    """Append a correct CRC, so a test reaches the check after the CRC."""
    return body + CRC.pack(zlib.crc32(body))


def _strip(packet: bytes) -> bytes:
    return packet[: -CRC.size]


def test_crc_is_standard_crc32() -> None:
    assert zlib.crc32(b"123456789") == 0xCBF43926


def test_documented_example_bytes() -> None:
    assert encode_sample(DOC_SAMPLE) == bytes.fromhex(DOC_SAMPLE_HEX)
    with_truth = Sample(
        seq=258,
        t=2.58,
        counts=(3100, 3105, 12900, 12890),
        status=Status.SOLENOID_LEFT | Status.LOCKED_LEFT,
        truth=GroundTruth("squat", 3, 0.5),
    )
    assert encode_sample(with_truth) == bytes.fromhex(DOC_TRUTH_HEX)
    command = CommandPacket(host_seq=7, lock_left=True, lock_right=False, echo_seq=258)
    assert encode_command(command) == bytes.fromhex(DOC_COMMAND_HEX)
    assert encode_hello(HelloPacket(host_seq=1)) == bytes.fromhex(DOC_HELLO_HEX)


def test_sizes() -> None:
    assert len(encode_sample(DOC_SAMPLE)) == 36
    assert len(encode_command(CommandPacket(1, False, False))) == 24
    assert len(encode_hello(HelloPacket(1))) == 20


STATUS_BITS = [s for s in Status if s is not Status.NONE]
statuses = st.lists(st.sampled_from(STATUS_BITS), max_size=9).map(
    lambda bits: Status(sum({int(b) for b in bits}))
)
activities = st.text(max_size=MAX_ACTIVITY_BYTES).filter(
    lambda s: len(s.encode("utf-8")) <= MAX_ACTIVITY_BYTES
)
truths = st.none() | st.builds(
    GroundTruth,
    activity=activities,
    lift_index=st.integers(-(2**31), 2**31 - 1),
    progress=st.floats(allow_nan=True, allow_infinity=True),
)
samples = st.builds(
    Sample,
    seq=st.integers(0, 2**32 - 1),
    t=st.integers(0, 2**53 // 2).map(lambda us: us / 1e6),
    counts=st.tuples(*[st.integers(0, 16383)] * 4),
    status=statuses,
    truth=truths,
)


def _same_truth(a: GroundTruth | None, b: GroundTruth | None) -> bool:
    if a is None or b is None:
        return a is b
    same_progress = (math.isnan(a.progress) and math.isnan(b.progress)) or a.progress == b.progress
    return a.activity == b.activity and a.lift_index == b.lift_index and same_progress


@given(samples)
def test_sample_round_trip(sample: Sample) -> None:
    out = decode_sample(encode_sample(sample))
    assert (out.seq, out.t, out.counts, out.status) == (
        sample.seq,
        sample.t,
        sample.counts,
        sample.status,
    )
    assert _same_truth(out.truth, sample.truth)


@given(
    st.integers(0, 2**32 - 1),
    st.booleans(),
    st.booleans(),
    st.none() | st.integers(0, 2**32 - 1),
)
def test_command_round_trip(seq: int, left: bool, right: bool, echo: int | None) -> None:
    packet = CommandPacket(host_seq=seq, lock_left=left, lock_right=right, echo_seq=echo)
    assert decode_command(encode_command(packet)) == packet
    assert decode(encode(packet)) == packet
    assert packet.as_lock_command().lock_left is left


@given(st.integers(0, 2**32 - 1))
def test_hello_round_trip(seq: int) -> None:
    assert decode(encode_hello(HelloPacket(seq))) == HelloPacket(seq)


def test_sequence_is_sent_modulo_2_32() -> None:
    out = decode_sample(encode_sample(Sample(seq=2**32 + 5, t=0.0, counts=(0, 0, 0, 0))))
    assert out.seq == 5


@pytest.mark.parametrize(
    ("new", "old", "diff"),
    [(5, 4, 1), (4, 5, -1), (0, 2**32 - 1, 1), (2**32 - 1, 0, -1), (7, 7, 0), (10, 2**32 - 10, 20)],
)
def test_seq_diff_wraps(new: int, old: int, diff: int) -> None:
    assert seq_diff(new, old) == diff


@given(samples, st.data())
def test_any_single_bit_flip_is_rejected(sample: Sample, data: st.DataObject) -> None:
    packet = bytearray(encode_sample(sample))
    bit = data.draw(st.integers(0, 8 * len(packet) - 1))
    packet[bit // 8] ^= 1 << (bit % 8)
    with pytest.raises(ProtocolError):
        decode(bytes(packet))


@given(st.binary(max_size=128))
def test_random_bytes_never_crash(data: bytes) -> None:
    try:
        decode(data)
    except ProtocolError as exc:
        assert exc.reason


def _raises(data: bytes, reason: str) -> ProtocolError:
    with pytest.raises(ProtocolError) as info:
        decode(data)
    assert info.value.reason == reason
    assert str(info.value).startswith(reason)
    return info.value


def test_short_packet() -> None:
    exc = _raises(b"EX\x01", "short")
    assert "3 bytes" in str(exc)
    _raises(b"", "short")


def test_bad_magic() -> None:
    good = encode_sample(DOC_SAMPLE)
    _raises(_reframe(b"XX" + _strip(good)[2:]), "magic")


def test_bad_crc() -> None:
    packet = bytearray(encode_sample(DOC_SAMPLE))
    packet[-1] ^= 0xFF
    exc = _raises(bytes(packet), "crc")
    assert "computed" in str(exc)
    packet = bytearray(encode_sample(DOC_SAMPLE))
    packet[20] ^= 0x01  # a status bit: caught by the CRC, not reported as valid data
    _raises(bytes(packet), "crc")


def test_unknown_version_is_rejected_after_the_crc() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE)))
    body[2] = 2
    exc = _raises(_reframe(bytes(body)), "version")
    assert "version 2" in str(exc)
    corrupted = bytearray(encode_sample(DOC_SAMPLE))
    corrupted[2] = 2  # without a matching CRC it is transmission damage, not a version
    _raises(bytes(corrupted), "crc")


def test_unknown_type() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE)))
    body[3] = 9
    exc = _raises(_reframe(bytes(body)), "type")
    assert "9" in str(exc)


def test_length_field_must_match_datagram() -> None:
    good = encode_sample(DOC_SAMPLE)
    _raises(good + b"\0", "length")
    _raises(good[:-5] + good[-4:], "length")
    magic, version, ptype, length, flags = HEADER.unpack_from(good)
    body = HEADER.pack(magic, version, ptype, length + 2, flags) + _strip(good)[8:] + b"\0\0"
    _raises(_reframe(body), "length")  # consistent framing, wrong size for a SAMPLE


def test_count_above_14_bits() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE)))
    struct.pack_into("<H", body, 8 + 16 + 2, 16384)  # left cam count
    exc = _raises(_reframe(bytes(body)), "counts")
    assert "encoder 1" in str(exc) and "16384" in str(exc)


def test_reserved_status_bits() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE)))
    struct.pack_into("<I", body, 8 + 12, 1 << 20)
    _raises(_reframe(bytes(body)), "status")


def test_unknown_flags() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE)))
    struct.pack_into("<H", body, 6, 0x8000)
    _raises(_reframe(bytes(body)), "flags")


def test_truth_flag_without_extension() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE)))
    struct.pack_into("<H", body, 6, 1)
    _raises(_reframe(bytes(body)), "length")


def test_command_reserved_bits() -> None:
    body = bytearray(_strip(encode_command(CommandPacket(1, True, True))))
    body[8 + 8] |= 0x04
    _raises(_reframe(bytes(body)), "reserved")
    body = bytearray(_strip(encode_command(CommandPacket(1, True, True))))
    body[8 + 10] = 1
    _raises(_reframe(bytes(body)), "reserved")


def test_decode_sample_rejects_a_command() -> None:
    with pytest.raises(ProtocolError) as info:
        decode_sample(encode_command(CommandPacket(1, False, False)))
    assert info.value.reason == "type"
    with pytest.raises(ProtocolError):
        decode_command(encode_sample(DOC_SAMPLE))


def test_encoder_refuses_what_the_decoder_would_reject() -> None:
    with pytest.raises(ProtocolError, match="counts"):
        encode_sample(Sample(seq=0, t=0.0, counts=(16384, 0, 0, 0)))
    with pytest.raises(ProtocolError, match="time"):
        encode_sample(Sample(seq=0, t=-1.0, counts=(0, 0, 0, 0)))
    with pytest.raises(ProtocolError, match="truth"):
        truth = GroundTruth("x" * (MAX_ACTIVITY_BYTES + 1))
        encode_sample(Sample(seq=0, t=0.0, counts=(0, 0, 0, 0), truth=truth))
    with pytest.raises(ProtocolError, match="range"):
        encode_command(CommandPacket(-1, False, False))
