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
    MAX_PACKET,
    SESSIONS,
    VERSION,
    ChallengePacket,
    CommandPacket,
    Frame,
    HelloPacket,
    JoinPacket,
    ProtocolError,
    VersionPacket,
    decode,
    decode_command,
    decode_frame,
    decode_sample,
    encode,
    encode_challenge,
    encode_command,
    encode_hello,
    encode_join,
    encode_sample,
    encode_version,
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
DOC_CHALLENGE_BYTES = bytes(range(0xA0, 0xB0))
DOC_CHALLENGE = ChallengePacket(hello_seq=5, challenge=DOC_CHALLENGE_BYTES,
                                unique_id=bytes(range(0x10, 0x1C)) + bytes(4),
                                firmware="exostudy-c 3.0")
DOC_JOIN = JoinPacket(host_seq=6, challenge=DOC_CHALLENGE_BYTES)
DOC_COMMAND = CommandPacket(host_seq=7, lock_left=True, lock_right=False, echo_seq=258)
DOC_HEARTBEAT = CommandPacket(host_seq=8, lock_left=True, lock_right=True, echo_seq=259,
                              stop_heartbeat=True)
#: The document's blocks, in its order: the exchange HELLO 5 .. COMMAND 8, and VERSION.
NAMES = ("sample", "sample_truth", "hello", "challenge", "join", "command",
         "command_heartbeat", "version")
#: What each block decodes to (packet, sender, receiver, device drop counts).
DOC_FRAMES = {
    "sample": Frame(DOC_SAMPLE, DEVICE, HOST, 1, 2, 3),
    "sample_truth": Frame(DOC_TRUTH, DEVICE, HOST),
    "hello": Frame(HelloPacket(5), HOST, 0),
    "challenge": Frame(DOC_CHALLENGE, DEVICE, HOST),
    "join": Frame(DOC_JOIN, HOST, DEVICE),
    "command": Frame(DOC_COMMAND, HOST, DEVICE),
    "command_heartbeat": Frame(DOC_HEARTBEAT, HOST, DEVICE),
    "version": Frame(VersionPacket(3, 3), 0, 0),
}


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
    vectors.c, given every block as NAME=HEX): `NAME VALUE` lines as a dict."""
    args = [f"{name}={vectors[name].hex()}" for name in NAMES]
    done = subprocess.run([str(c_device.vectors_binary()), *args], capture_output=True,
                          text=True, timeout=60, check=True)
    return dict(line.split(" ", 1) for line in done.stdout.splitlines())


def _python_encoded() -> dict[str, bytes]:
    """The eight documented packets as the Python implementation encodes them."""
    return {"sample": encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST, 1, 2, 3),
            "sample_truth": encode_sample(DOC_TRUTH, KEY, DEVICE, HOST),
            "hello": encode_hello(HelloPacket(5), KEY, HOST),
            "challenge": encode_challenge(DOC_CHALLENGE, KEY, DEVICE, HOST),
            "join": encode_join(DOC_JOIN, KEY, HOST, DEVICE),
            "command": encode_command(DOC_COMMAND, KEY, HOST, DEVICE),
            "command_heartbeat": encode_command(DOC_HEARTBEAT, KEY, HOST, DEVICE),
            "version": encode_version(VersionPacket(3, 3), KEY)}


def test_the_document_has_the_eight_vectors_with_correct_tags() -> None:
    vectors = _doc_vectors()
    assert tuple(vectors) == NAMES
    sizes = {"sample": 92, "sample_truth": 110, "hello": 64, "challenge": 112, "join": 80,
             "command": 68, "command_heartbeat": 68, "version": 44}
    assert {name: len(data) for name, data in vectors.items()} == sizes
    for data in vectors.values():
        assert data[2] == VERSION == 3
        assert data[-TAG_BYTES:] == _hmac_sha256(KEY, data[:-TAG_BYTES])


def test_python_encodes_and_decodes_the_documented_vectors_byte_for_byte() -> None:
    vectors = _doc_vectors()
    assert _python_encoded() == vectors
    for name, data in vectors.items():
        frame = DOC_FRAMES[name]
        assert decode_frame(data, KEY) == frame, name
        if name != "sample":  # (encode() sends no drop counts)
            assert encode(frame.packet, KEY, frame.sender or HOST, frame.receiver) == data


@pytest.mark.parametrize("name", NAMES)
def test_every_one_bit_change_of_a_vector_is_rejected(name: str) -> None:
    data = _doc_vectors()[name]
    for bit in range(8 * len(data)):
        changed = bytearray(data)
        changed[bit // 8] ^= 1 << (bit % 8)
        with pytest.raises(ProtocolError):
            decode(bytes(changed), KEY)


def test_the_c_core_encodes_and_accepts_the_documented_vectors() -> None:
    """The C core's side (firmware/ports/linux-sim/vectors.c): its encoders make the
    device's packets byte for byte, its decoder accepts all eight, and no one-bit
    change of any of them gets past it."""
    vectors = _doc_vectors()
    out = _c_vector_tool(vectors)
    for name in ("sample", "sample_truth", "challenge", "version"):
        assert bytes.fromhex(out[f"wire_{name}"]) == vectors[name], name
    assert [out[f"decode_ok_{name}"] for name in NAMES] == ["1"] * len(NAMES)
    bits = 8 * sum(len(v) for v in vectors.values())
    assert out["decoder_flips_rejected"] == f"{bits} {bits}"


def test_the_c_device_makes_the_documented_samples_and_ignores_any_changed_bit() -> None:
    """The whole C device, not only its encoder: booted with the document's session,
    challenge and identity, fed the document's HELLO, JOIN and COMMANDs on a simulated
    clock (plus a forged, replayed and stale datagram for the drop counts), with
    emulated AS5048A chips showing the document's counts, it sends the document's
    CHALLENGE and SAMPLEs byte for byte; and no one-bit change of the host's packets
    gets past it or changes the device's state."""
    vectors = _doc_vectors()
    out = _c_vector_tool(vectors)
    assert bytes.fromhex(out["device_challenge"]) == vectors["challenge"]
    assert bytes.fromhex(out["device_sample"]) == vectors["sample"]
    assert bytes.fromhex(out["device_sample_truth"]) == vectors["sample_truth"]
    assert out["device_join_streams"] == "1"
    assert out["device_command_energises"] == "1"
    bits = 8 * sum(len(vectors[n]) for n in ("hello", "join", "command", "command_heartbeat"))
    assert out["device_flips_ignored"] == f"{bits} {bits}"


def test_sizes() -> None:
    assert len(encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)) == 92
    assert len(encode_command(CommandPacket(1, False, False, 0), KEY, HOST, DEVICE)) == 68
    assert len(encode_hello(HelloPacket(1), KEY, HOST)) == 64
    longest = GroundTruth("x" * MAX_ACTIVITY_BYTES)
    assert len(encode_sample(Sample(0, 0.0, (0, 0, 0, 0), truth=longest), KEY, DEVICE,
                             HOST)) == MAX_PACKET == 169


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
sessions = st.integers(1, 2**64 - 1)
u32 = st.integers(0, 2**32 - 1)


def _same_truth(a: GroundTruth | None, b: GroundTruth | None) -> bool:
    if a is None or b is None:
        return a is b
    same_progress = (math.isnan(a.progress) and math.isnan(b.progress)) or a.progress == b.progress
    return a.activity == b.activity and a.lift_index == b.lift_index and same_progress


@given(samples, sessions, sessions, u32, u32)
def test_sample_round_trip(sample: Sample, sender: int, receiver: int, drops: int,
                           stale: int) -> None:
    frame = decode_frame(encode_sample(sample, KEY, sender, receiver, drops, 3, stale), KEY)
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
    assert (frame.device_auth_drops, frame.device_replay_drops,
            frame.device_stale_drops) == (drops, 3, stale)


@given(u32, st.booleans(), st.booleans(), u32, st.booleans(), sessions, sessions)
def test_command_round_trip(seq: int, left: bool, right: bool, echo: int, stop: bool,
                            sender: int, receiver: int) -> None:
    packet = CommandPacket(host_seq=seq, lock_left=left, lock_right=right, echo_seq=echo,
                           stop_heartbeat=stop)
    assert decode_frame(encode_command(packet, KEY, sender, receiver), KEY) == Frame(
        packet, sender, receiver)
    assert decode_command(encode(packet, KEY, HOST, DEVICE), KEY) == packet
    lock = packet.as_lock_command()
    assert (lock.lock_left, lock.lock_right, lock.stop_heartbeat) == (left, right, stop)


@given(u32, sessions)
def test_hello_round_trip(seq: int, sender: int) -> None:
    assert decode_frame(encode_hello(HelloPacket(seq), KEY, sender), KEY) == Frame(
        HelloPacket(seq), sender, 0)


printable = st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), min_size=1,
                    max_size=16)


@given(u32, u32, st.binary(min_size=16, max_size=16), st.binary(min_size=16, max_size=16),
       printable, sessions, sessions)
def test_challenge_round_trip(hello: int, lifetime: int, challenge: bytes, uid: bytes,
                              firmware: str, sender: int, receiver: int) -> None:
    packet = ChallengePacket(hello, challenge, uid, firmware, lifetime)
    data = encode_challenge(packet, KEY, sender, receiver)
    assert decode_frame(data, KEY) == Frame(packet, sender, receiver)


@given(u32, st.binary(min_size=16, max_size=16), sessions, sessions)
def test_join_round_trip(seq: int, challenge: bytes, sender: int, receiver: int) -> None:
    packet = JoinPacket(seq, challenge)
    assert decode_frame(encode_join(packet, KEY, sender, receiver), KEY) == Frame(
        packet, sender, receiver)


@given(st.integers(0, 255), st.integers(0, 255))
def test_version_round_trip_whatever_the_versions(a: int, b: int) -> None:
    packet = VersionPacket(min(a, b), max(a, b))
    data = encode_version(packet, KEY)
    assert data[2] == packet.highest  # the sender's highest version is its version byte
    assert decode_frame(data, KEY) == Frame(packet, 0, 0)


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
    exc = _raises(b"EX\x03", "short")
    assert "3 bytes" in str(exc)
    _raises(b"", "short")  # an empty datagram is a drop like any other
    _raises(encode_version(VersionPacket(3, 3), KEY)[:-1], "short")  # 43 < 44


def test_bad_magic() -> None:
    good = encode_sample(DOC_SAMPLE, KEY, DEVICE, HOST)
    _raises(_sign(b"XX" + _strip(good)[2:]), "magic")


def test_a_packet_signed_with_another_key_is_not_authentic() -> None:
    forged = encode_command(CommandPacket(9, True, True, 0), OTHER_KEY, HOST, DEVICE)
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
    good = _strip(encode_command(CommandPacket(1, True, True, 0), KEY, HOST, DEVICE))
    body = bytearray(good)
    body[8 + 8] |= 0x04
    _raises(_sign(bytes(body)), "reserved")
    body = bytearray(good)
    body[8 + 10] = 1
    _raises(_sign(bytes(body)), "reserved")


def test_decode_sample_rejects_a_command() -> None:
    with pytest.raises(ProtocolError) as info:
        decode_sample(encode_command(CommandPacket(1, False, False, 0), KEY, HOST, DEVICE), KEY)
    assert info.value.reason == "unexpected"
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
        encode_command(CommandPacket(-1, False, False, 0), KEY, HOST, DEVICE)
    with pytest.raises(ProtocolError, match="range"):
        encode_hello(HelloPacket(1), KEY, -1)


def _resign(packet: bytes, offset: int, fmt: str, value: int) -> bytes:
    """`packet` with one field changed and a correct tag again."""
    body = bytearray(_strip(packet))
    struct.pack_into(fmt, body, offset, value)
    return _sign(bytes(body))


def test_a_hello_names_receiver_session_0_and_no_sender_is_0() -> None:
    hello = encode_hello(HelloPacket(5), KEY, HOST)
    _raises(_resign(hello, len(hello) - TAG_BYTES - 8, "<Q", DEVICE), "reserved")
    _raises(_resign(hello, len(hello) - TAG_BYTES - 16, "<Q", 0), "reserved")
    join = encode_join(DOC_JOIN, KEY, HOST, DEVICE)
    _raises(_resign(join, len(join) - TAG_BYTES - 16, "<Q", 0), "reserved")
    _raises(_resign(join, 8 + 4, "<I", 1), "reserved")  # JOIN's reserved bytes
    with pytest.raises(ProtocolError, match="reserved"):
        encode_hello(HelloPacket(1), KEY, 0)


def test_a_challenge_names_printable_nul_padded_firmware() -> None:
    good = encode_challenge(DOC_CHALLENGE, KEY, DEVICE, HOST)
    for bad in (b"\0" * 16, b"exo\0sim" + b"\0" * 9, b"exo\x7fsim" + b"\0" * 9,
                b"\0exostudy" + b"\0" * 7):
        body = bytearray(_strip(good))
        body[8 + 40 : 8 + 56] = bad
        _raises(_sign(bytes(body)), "identity")
    with pytest.raises(ProtocolError, match="identity"):
        encode_challenge(ChallengePacket(1, bytes(16), bytes(16), "x" * 17), KEY, DEVICE, HOST)


def test_a_version_packet_is_read_whatever_its_version_byte_but_must_be_ordered() -> None:
    old = encode_version(VersionPacket(1, 2), KEY)
    assert old[2] == 2 and decode(old, KEY) == VersionPacket(1, 2)
    _raises(_resign(old, 8, "<B", 3), "reserved")  # lowest 3 > highest 2
    _raises(_resign(old, 6, "<H", 1), "flags")
    _raises(old + b"\0", "length")


def test_the_first_failure_in_the_documented_order_names_the_drop() -> None:
    """A packet wrong in several ways is dropped for the first check of the table."""
    sample = encode_sample(DOC_TRUTH, KEY, DEVICE, HOST)
    body = bytearray(_strip(sample))
    body[-16 - 1] = 0xFF  # the activity's last byte: not UTF-8 ("truth")
    _raises(_sign(bytes(body)), "truth")
    struct.pack_into("<Q", body, len(body) - 16, 0)  # and sender session 0 ("reserved")
    _raises(_sign(bytes(body)), "reserved")
    struct.pack_into("<I", body, 8 + 12, 1 << 11)  # and a reserved status bit
    _raises(_sign(bytes(body)), "status")
    struct.pack_into("<H", body, 8 + 16, 20000)  # and a count above 14 bits
    _raises(_sign(bytes(body)), "counts")
    struct.pack_into("<H", body, 6, 3)  # and an unknown flag
    _raises(_sign(bytes(body)), "flags")
    body[3] = 7  # and an unknown type
    _raises(_sign(bytes(body)), "type")
    body[2] = 2  # and version 2
    _raises(_sign(bytes(body)), "version")
    _raises(bytes(body) + bytes(32), "auth")  # and a wrong tag
    _raises(_sign(bytes(body[:-1])), "length")
    _raises(b"XY" + _sign(bytes(body[:-1]))[2:], "magic")
