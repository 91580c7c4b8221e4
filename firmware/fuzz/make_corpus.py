#!/usr/bin/env python3
"""Write the fuzz harnesses' seed corpus (firmware/fuzz/corpus/<harness>/).

Run by hand after a protocol change (`python3 firmware/fuzz/make_corpus.py`); the
files are kept in the tree. Seeds: the protocol document's test vectors (read from
docs/device-protocol.md), a few damaged copies, and short programs for the device
harness that open a session, lock, replay, flood and wait out the watchdog, so that the
fuzzer starts from deep states instead of having to find a handshake by chance.
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

HERE = Path(__file__).resolve().parent
DOC = HERE.parent.parent / "docs" / "device-protocol.md"
OUT = HERE / "corpus"


def vectors() -> dict[str, bytes]:
    """The hex blocks of the document, by name."""
    text = DOC.read_text()
    found = {}
    for name, body in re.findall(r"```hex (\w+)\n(.*?)```", text, re.S):
        found[name] = bytes.fromhex(body)
    return found


def write(harness: str, name: str, data: bytes) -> None:
    folder = OUT / harness
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)


# --- device programs (the step encoding of fuzz_device.c) ---
def advance(ms: int, stalled: bool = False) -> bytes:
    return bytes([0x80 if stalled else 0x00]) + struct.pack("<H", (3 << 14) | ms)


HELLO = bytes([2, 0x00, 0x00])
JOIN = bytes([3, 0x00, 0x00])
JOIN_OLD = bytes([3, 0x00, 0x08])  # challenge bytes of the CHALLENGE before the last


def command(locks: int, back: int = 0, stop_heartbeat: bool = False) -> bytes:
    """COMMAND of the joined session, next host_seq, echoing the newest sample minus
    `back` (0..31)."""
    return bytes([4, 0x00, 0x08, locks | (4 if stop_heartbeat else 0), back])


REPLAY_LAST = bytes([6, 0])
EMPTY = bytes([8])
FOREIGN_LAST = bytes([0x87])
OTHER_VERSION = bytes([11, 0x00, 0x00, 0x00])  # a HELLO with version byte 2

SESSION = HELLO + JOIN + advance(10)
PROGRAMS = {
    "lock_then_watchdog": SESSION + command(3) + advance(10) + command(1) + advance(200),
    "delayed_lock": SESSION + advance(10) + command(0) + advance(150) + command(3, 12)
    + command(3, 10) + command(3, 9) + advance(20),
    "replayed_join": SESSION + command(3) + REPLAY_LAST + HELLO + advance(60) + HELLO
    + JOIN_OLD + advance(20) + REPLAY_LAST + advance(120),
    "hello_mid_session": SESSION + command(3) + advance(10) + HELLO + command(2) + advance(10)
    + HELLO + REPLAY_LAST + advance(120),
    "flood": SESSION + command(1) + b"".join([EMPTY, REPLAY_LAST] * 6) + command(3) + advance(30),
    "foreign_and_version": SESSION + FOREIGN_LAST + OTHER_VERSION + advance(500) + OTHER_VERSION
    + advance(600, stalled=True) + OTHER_VERSION,
    "stop_heartbeat": SESSION + command(1, stop_heartbeat=True) + advance(50) + command(1, 0, True)
    + advance(200),
    "challenge_expiry": HELLO + advance(1100) + JOIN + HELLO + advance(40) + HELLO + advance(20)
    + HELLO + JOIN + advance(20) + command(3) + advance(300, stalled=True),
    "rejoin": SESSION + command(3) + advance(10) + HELLO + advance(60) + HELLO + JOIN
    + advance(10) + command(3) + advance(10) + command(0) + advance(20),
}


# --- network frames ---
DEV_MAC = bytes.fromhex("020000000002")
HOST_MAC = bytes.fromhex("020000000001")
OTHER_MAC = bytes.fromhex("020000000007")
DEV_IP = bytes([192, 168, 250, 2])
HOST_IP = bytes([192, 168, 250, 1])
OTHER_IP = bytes([192, 168, 250, 7])


def checksum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def ipv4(src: bytes, proto: int, payload: bytes) -> bytes:
    head = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(payload), 1, 0x4000, 64, proto, 0,
                       src, DEV_IP)
    head = head[:10] + struct.pack("!H", checksum(head)) + head[12:]
    return head + payload


def udp_frame(src_ip: bytes, src_mac: bytes, payload: bytes) -> bytes:
    udp = struct.pack("!HHHH", 50000, 47300, 8 + len(payload), 0) + payload
    pseudo = src_ip + DEV_IP + struct.pack("!BBH", 0, 17, len(udp))
    udp = udp[:6] + struct.pack("!H", checksum(pseudo + udp)) + udp[8:]
    return (DEV_MAC + src_mac + b"\x08\x00" + ipv4(src_ip, 17, udp)).ljust(60, b"\0")


def arp_request(sender_mac: bytes, sender_ip: bytes) -> bytes:
    body = struct.pack("!HHBBH6s4s6s4s", 1, 0x0800, 6, 4, 1, sender_mac, sender_ip, b"\0" * 6,
                       DEV_IP)
    return (b"\xff" * 6 + sender_mac + b"\x08\x06" + body).ljust(60, b"\0")


def icmp_echo(src_ip: bytes) -> bytes:
    icmp = struct.pack("!BBHHH", 8, 0, 0, 7, 1) + b"ping"
    icmp = icmp[:2] + struct.pack("!H", checksum(icmp)) + icmp[4:]
    return (DEV_MAC + HOST_MAC + b"\x08\x00" + ipv4(src_ip, 1, icmp)).ljust(60, b"\0")


def raw_frames(*frames: bytes) -> bytes:
    """A net-harness program of raw frames (op 0), then one receive (op 5)."""
    out = b""
    for f in frames:
        out += b"\x00" + struct.pack("<H", len(f)) + f
    return out + b"\x05"


def main() -> None:
    vec = vectors()
    assert len(vec) >= 8, f"expected the document's vectors, found {sorted(vec)}"
    for name, data in vec.items():
        write("wire_raw", name, data)
        write("wire_auth", name, b"\x00" + data)
        damaged = bytearray(data)
        damaged[8] ^= 0x80
        write("wire_raw", name + "_damaged", bytes(damaged))
        write("wire_auth", name + "_reauth_fix_length", b"\x03" + bytes(damaged))
    write("wire_raw", "empty", b"")
    for name, program in PROGRAMS.items():
        write("device", name, b"\x00" + program)
    hello = vec["hello"]
    write("net", "udp_from_host", raw_frames(udp_frame(HOST_IP, HOST_MAC, hello)))
    write("net", "udp_from_other", raw_frames(udp_frame(OTHER_IP, OTHER_MAC, hello)))
    write("net", "arp_then_udp", raw_frames(arp_request(HOST_MAC, HOST_IP),
                                            udp_frame(HOST_IP, HOST_MAC, vec["command"])))
    write("net", "ping", raw_frames(icmp_echo(HOST_IP)))
    write("net", "queue_full", raw_frames(*[udp_frame(HOST_IP, HOST_MAC, hello)] * 6))
    # A send before and after the host's MAC is known (op 6), and the built-frame ops.
    write("net", "send_then_arp", b"\x06\x40\x00\x00\x00" + raw_frames(
        arp_request(HOST_MAC, HOST_IP)) + b"\x06\x40\x00\x10\x27")
    write("net", "built_frames", bytes([1, 0x00, 0x00, 0x10, 0x00, 1, 0]) + b"x" * 16
          + bytes([0x34, 0x12, 3, 0, 0, 4, 0, 7, 0, 1, 0, 4, 0, 5]))


if __name__ == "__main__":
    main()
