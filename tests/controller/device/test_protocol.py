"""The wire format: exact bytes (the documented test vectors), round trips, the
authentication tag, and every way a packet can be rejected."""

from __future__ import annotations

import hashlib
import math
import re
import struct
import subprocess
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from controller.device.auth import TAG_BYTES, tag
from controller.device.base import GroundTruth, Sample, Status
from controller.device.protocol import (
    HEADER,
    MAX_ACTIVITY_BYTES,
    SESSIONS,
    VERSION,
    CommandPacket,
    Frame,
    HelloPacket,
    ProtocolError,
    decode,
    decode_command,
    decode_frame,
    decode_sample,
    encode,
    encode_command,
    encode_hello,
    encode_sample,
    seq_diff,
)
from tests import c_device

DOC = Path(__file__).resolve().parents[3] / "docs" / "device-protocol.md"
# The test-vector key and sessions of docs/device-protocol.md.
KEY = bytes(range(32))
DEVICE = 0x1122334455667788
HOST = 0x0123456789ABCDEF
OTHER_KEY = bytes(range(1, 33))

DOC_SAMPLE = Sample(
    seq=258,
    t=2.58,
    counts=(3100, 3105, 12900, 12890),
    status=Status.SOLENOID_LEFT | Status.LOCKED_LEFT,
)
DOC_TRUTH = Sample(seq=258, t=2.58, counts=(3100, 3105, 12900, 12890),
                   status=Status.SOLENOID_LEFT | Status.LOCKED_LEFT,
                   truth=GroundTruth("squat", 3, 0.5))
DOC_COMMAND = CommandPacket(host_seq=7, lock_left=True, lock_right=False, echo_seq=258)


def _doc_vectors() -> dict[str, bytes]:
    """The ```hex NAME blocks of the protocol document."""
    found = re.findall(r"```hex (\w+)\n(.*?)```", DOC.read_text(), flags=re.S)
    return {name: bytes.fromhex(" ".join(body.split())) for name, body in found}


def _hmac_sha256(key: bytes, data: bytes) -> bytes:
    """HMAC from its definition (RFC 2104) on plain SHA-256: an oracle independent of
    the `hmac` module the code uses."""
    block = key.ljust(64, b"\0")
    inner = hashlib.sha256(bytes(b ^ 0x36 for b in block) + data).digest()
    return hashlib.sha256(bytes(b ^ 0x5C for b in block) + inner).digest()


def _sign(body: bytes, key: bytes = KEY) -> bytes:
    """A correct tag on a modified body, so a test reaches the checks after the tag."""
    return body + tag(key, body)


def _strip(packet: bytes) -> bytes:
    return packet[:-TAG_BYTES]


def test_hmac_matches_its_definition_and_rfc4231_case_2() -> None:
    # RFC 4231, test case 2: key "Jefe", data "what do ya want for nothing?".
    expected = "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"
    assert tag(b"Jefe", b"what do ya want for nothing?").hex() == expected
    assert _hmac_sha256(b"Jefe", b"what do ya want for nothing?").hex() == expected


def _c_vector_tool(vectors: dict[str, bytes]) -> dict[str, str]:
    """What the C core makes of the document's vectors (firmware/ports/linux-sim/
    vectors.c): `NAME VALUE` lines as a dict."""
    done = subprocess.run([str(c_device.vectors_binary()), vectors["hello"].hex(),
                           vectors["command"].hex()], capture_output=True, text=True,
                          timeout=60, check=True)
    return dict(line.split(" ", 1) for line in done.stdout.splitlines())


def _encoded(implementation: str, vectors: dict[str, bytes]) -> dict[str, bytes]:
    """The four documented packets as `implementation` encodes them."""
    if implementation == "python":
        return {"sample": encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST, 1, 2),
                "sample_truth": encode_sample(DOC_TRUTH, KEY, DEVICE, HOST),
                "command": encode_command(DOC_COMMAND, KEY, HOST, DEVICE),
                "hello": encode_hello(HelloPacket(1), KEY, HOST)}
    out = _c_vector_tool(vectors)
    return {name: bytes.fromhex(out[f"wire_{name}"]) for name in vectors}


@pytest.mark.parametrize("implementation", c_device.IMPLEMENTATIONS)
def test_documented_test_vectors(implementation: str) -> None:
    vectors = _doc_vectors()
    assert set(vectors) == {"sample", "sample_truth", "command", "hello"}
    encoded = _encoded(implementation, vectors)
    assert encoded["sample"] == vectors["sample"]
    assert encoded["sample_truth"] == vectors["sample_truth"]
    assert encoded["command"] == vectors["command"]
    assert encoded["hello"] == vectors["hello"]
    for data in vectors.values():
        assert data[2] == VERSION == 2
        assert data[-TAG_BYTES:] == _hmac_sha256(KEY, data[:-TAG_BYTES])
    if implementation == "python":
        frame = decode_frame(vectors["sample"], KEY)
        assert frame == Frame(DOC_SAMPLE, DEVICE, HOST, 1, 2)
        assert decode_frame(vectors["command"], KEY) == Frame(DOC_COMMAND, HOST, DEVICE)
        assert decode_frame(vectors["hello"], KEY) == Frame(HelloPacket(1), HOST, 0)
    else:
        # The C decoder accepts all four, the COMMAND and HELLO with the document's
        # fields (sessions, host_seq, echo, lock bits: checked inside the tool).
        out = _c_vector_tool(vectors)
        assert [out[f"decode_ok_{name}"] for name in sorted(vectors)] == ["1"] * 4


def test_the_c_device_makes_the_documented_samples_and_ignores_any_changed_bit() -> None:
    """The whole C device, not only its encoder: booted with the document's session,
    fed the document's HELLO and COMMAND (plus one forged and two replayed commands for
    the drop counts) on a simulated clock, with emulated AS5048A chips showing the
    document's counts, it sends the document's SAMPLEs byte for byte; and no one-bit
    change of any packet gets past its decoder or changes the device's state."""
    vectors = _doc_vectors()
    out = _c_vector_tool(vectors)
    assert bytes.fromhex(out["device_sample"]) == vectors["sample"]
    assert bytes.fromhex(out["device_sample_truth"]) == vectors["sample_truth"]
    assert out["device_hello_streams"] == "1"
    assert out["device_command_energises"] == "1"
    bits = 8 * sum(len(v) for v in vectors.values())
    assert out["decoder_flips_rejected"] == f"{bits} {bits}"
    bits = 8 * (len(vectors["hello"]) + len(vectors["command"]))
    assert out["device_flips_ignored"] == f"{bits} {bits}"


def test_sizes() -> None:
    assert len(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)) == 88
    assert len(encode_command(CommandPacket(1, False, False), KEY, HOST, DEVICE)) == 68
    assert len(encode_hello(HelloPacket(1), KEY, HOST)) == 64


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
sessions = st.integers(0, 2**64 - 1)


def _same_truth(a: GroundTruth | None, b: GroundTruth | None) -> bool:
    if a is None or b is None:
        return a is b
    same_progress = (math.isnan(a.progress) and math.isnan(b.progress)) or a.progress == b.progress
    return a.activity == b.activity and a.lift_index == b.lift_index and same_progress


@given(samples, sessions, sessions, st.integers(0, 2**32 - 1))
def test_sample_round_trip(sample: Sample, sender: int, receiver: int, drops: int) -> None:
    frame = decode_frame(encode_sample(sample, KEY, sender, receiver, drops, 3), KEY)
    out = frame.packet
    assert isinstance(out, Sample)
    assert (out.seq, out.t, out.counts, out.status) == (
        sample.seq,
        sample.t,
        sample.counts,
        sample.status,
    )
    assert _same_truth(out.truth, sample.truth)
    assert (frame.sender, frame.receiver) == (sender, receiver)
    assert (frame.device_auth_drops, frame.device_replay_drops) == (drops, 3)


@given(
    st.integers(0, 2**32 - 1),
    st.booleans(),
    st.booleans(),
    st.none() | st.integers(0, 2**32 - 1),
)
def test_command_round_trip(seq: int, left: bool, right: bool, echo: int | None) -> None:
    packet = CommandPacket(host_seq=seq, lock_left=left, lock_right=right, echo_seq=echo)
    assert decode_command(encode_command(packet, KEY, HOST, DEVICE), KEY) == packet
    assert decode(encode(packet, KEY, HOST, DEVICE), KEY) == packet
    assert packet.as_lock_command().lock_left is left


@given(st.integers(0, 2**32 - 1))
def test_hello_round_trip(seq: int) -> None:
    assert decode(encode_hello(HelloPacket(seq), KEY, HOST), KEY) == HelloPacket(seq)


def test_sequence_is_sent_modulo_2_32() -> None:
    data = encode_sample(Sample(seq=2**32 + 5, t=0.0, counts=(0, 0, 0, 0)), KEY, DEVICE, HOST)
    assert decode_sample(data, KEY).seq == 5


@pytest.mark.parametrize(
    ("new", "old", "diff"),
    [(5, 4, 1), (4, 5, -1), (0, 2**32 - 1, 1), (2**32 - 1, 0, -1), (7, 7, 0), (10, 2**32 - 10, 20)],
)
def test_seq_diff_wraps(new: int, old: int, diff: int) -> None:
    assert seq_diff(new, old) == diff


@given(samples, st.data())
def test_any_single_bit_flip_is_rejected(sample: Sample, data: st.DataObject) -> None:
    packet = bytearray(encode_sample(sample, KEY, DEVICE, HOST))
    bit = data.draw(st.integers(0, 8 * len(packet) - 1))
    packet[bit // 8] ^= 1 << (bit % 8)
    with pytest.raises(ProtocolError):
        decode(bytes(packet), KEY)


@given(st.binary(max_size=160))
def test_random_bytes_never_crash(data: bytes) -> None:
    try:
        decode(data, KEY)
    except ProtocolError as exc:
        assert exc.reason


def _raises(data: bytes, reason: str, key: bytes = KEY) -> ProtocolError:
    with pytest.raises(ProtocolError) as info:
        decode(data, key)
    assert info.value.reason == reason
    assert str(info.value).startswith(reason)
    return info.value


def test_short_packet() -> None:
    exc = _raises(b"EX\x02", "short")
    assert "3 bytes" in str(exc)
    _raises(b"", "short")


def test_bad_magic() -> None:
    good = encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)
    _raises(_sign(b"XX" + _strip(good)[2:]), "magic")


def test_a_packet_signed_with_another_key_is_not_authentic() -> None:
    forged = encode_command(CommandPacket(9, True, True), OTHER_KEY, HOST, DEVICE)
    exc = _raises(forged, "auth")
    assert "authentication" in str(exc)
    packet = bytearray(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST))
    packet[20] ^= 0x01  # a status bit: caught by the tag, not reported as valid data
    _raises(bytes(packet), "auth")
    packet = bytearray(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST))
    struct.pack_into("<Q", packet, len(packet) - TAG_BYTES - SESSIONS.size, HOST)
    _raises(bytes(packet), "auth")  # the sessions are covered by the tag too


def test_unknown_version_is_rejected_after_the_tag() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)))
    body[2] = 1
    exc = _raises(_sign(bytes(body)), "version")
    assert "version 1" in str(exc)
    damaged = bytearray(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST))
    damaged[2] = 1  # without a matching tag it is damage or forgery, not a version
    _raises(bytes(damaged), "auth")


def test_unknown_type() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)))
    body[3] = 9
    exc = _raises(_sign(bytes(body)), "type")
    assert "9" in str(exc)


def test_length_field_must_match_datagram() -> None:
    good = encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)
    _raises(good + b"\0", "length")
    _raises(good[:-5], "length")
    magic, version, ptype, length, flags = HEADER.unpack_from(good)
    payload = _strip(good)[8 : 8 + length]
    trailer = _strip(good)[8 + length :]
    body = HEADER.pack(magic, version, ptype, length + 2, flags) + payload + b"\0\0" + trailer
    _raises(_sign(body), "length")  # consistent framing, wrong size for a SAMPLE


def test_count_above_14_bits() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)))
    struct.pack_into("<H", body, 8 + 16 + 2, 16384)  # left cam count
    exc = _raises(_sign(bytes(body)), "counts")
    assert "encoder 1" in str(exc) and "16384" in str(exc)


def test_reserved_status_bits() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)))
    struct.pack_into("<I", body, 8 + 12, 1 << 20)
    _raises(_sign(bytes(body)), "status")


def test_unknown_flags() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)))
    struct.pack_into("<H", body, 6, 0x8000)
    _raises(_sign(bytes(body)), "flags")


def test_truth_flag_without_extension() -> None:
    body = bytearray(_strip(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)))
    struct.pack_into("<H", body, 6, 1)
    _raises(_sign(bytes(body)), "length")


def test_command_reserved_bits() -> None:
    good = _strip(encode_command(CommandPacket(1, True, True), KEY, HOST, DEVICE))
    body = bytearray(good)
    body[8 + 8] |= 0x04
    _raises(_sign(bytes(body)), "reserved")
    body = bytearray(good)
    body[8 + 10] = 1
    _raises(_sign(bytes(body)), "reserved")


def test_decode_sample_rejects_a_command() -> None:
    with pytest.raises(ProtocolError) as info:
        decode_sample(encode_command(CommandPacket(1, False, False), KEY, HOST, DEVICE), KEY)
    assert info.value.reason == "type"
    with pytest.raises(ProtocolError):
        decode_command(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST), KEY)


def test_encoder_refuses_what_the_decoder_would_reject() -> None:
    with pytest.raises(ProtocolError, match="counts"):
        encode_sample(Sample(seq=0, t=0.0, counts=(16384, 0, 0, 0)), KEY, DEVICE, HOST)
    with pytest.raises(ProtocolError, match="time"):
        encode_sample(Sample(seq=0, t=-1.0, counts=(0, 0, 0, 0)), KEY, DEVICE, HOST)
    with pytest.raises(ProtocolError, match="truth"):
        truth = GroundTruth("x" * (MAX_ACTIVITY_BYTES + 1))
        encode_sample(Sample(seq=0, t=0.0, counts=(0, 0, 0, 0), truth=truth), KEY, DEVICE,
                      HOST)
    with pytest.raises(ProtocolError, match="range"):
        encode_command(CommandPacket(-1, False, False), KEY, HOST, DEVICE)
    with pytest.raises(ProtocolError, match="range"):
        encode_hello(HelloPacket(1), KEY, -1)
