#!/usr/bin/env python3
"""Write the emulation provisioning block that QEMU loads for the mps2-an500 firmware.

EMULATION ONLY (firmware/ports/mps2-an500/emu_prov.h has the layout and the reasons):
the block carries the link key, the addresses, a unique id, and a boot seed drawn
here from the operating system's random source. Write a new block before every start
of the emulator: the seed is where the device's session numbers come from.

    python3 tools/emu_block.py --key-file var/device.key --out block.bin
    qemu-system-arm -M mps2-an500 ... -device loader,file=block.bin,addr=0x003FF000,force-raw=on

Standard library only, so that it runs without the project's virtual environment.
"""

from __future__ import annotations

import argparse
import hashlib
import hmac
import ipaddress
import os
import struct
import zlib

ADDRESS = 0x003FF000  # where the firmware's linker script expects the block
KEY_BYTES = 32


def read_key(path: str) -> bytes:
    """The 32-byte link key from a key file of 64 hex digits."""
    with open(path, encoding="ascii") as f:
        text = f.read().strip()
    key = bytes.fromhex(text)
    if len(key) != KEY_BYTES:
        raise SystemExit(f"{path}: a key file holds {KEY_BYTES * 2} hex digits, not {len(text)}")
    return key


def default_device_id(key: bytes) -> bytes:
    """The simulated devices' default unique id, so that the emulated board is named
    the same way: the first 16 bytes of HMAC-SHA256(key, "exostudy simulated device")."""
    return hmac.new(key, b"exostudy simulated device", hashlib.sha256).digest()[:16]


def block(key: bytes, device_ip: str, netmask: str, host_ip: str, mac: bytes, port: int,
          unique_id: bytes, seed: bytes) -> bytes:
    """The 128 bytes: the Nucleo provisioning block, then the emulation part."""
    prov = (b"EXPV" + struct.pack("<HH", 1, 64) + key
            + ipaddress.IPv4Address(device_ip).packed + ipaddress.IPv4Address(netmask).packed
            + ipaddress.IPv4Address(host_ip).packed + mac + struct.pack("<H", port))
    prov += struct.pack("<I", zlib.crc32(prov))
    ext = b"EXEM" + struct.pack("<HH", 1, 64) + unique_id.ljust(16, b"\0") + seed + bytes(4)
    ext += struct.pack("<I", zlib.crc32(ext))
    assert len(prov) == 64 and len(ext) == 64
    return prov + ext


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--key-file", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--device-ip", default="10.0.2.15")  # QEMU user networking's guest
    parser.add_argument("--netmask", default="255.255.255.0")
    parser.add_argument("--host-ip", default="10.0.2.2")  # ... and its host (the gateway)
    parser.add_argument("--mac", default="52:54:00:12:34:56")
    parser.add_argument("--port", type=int, default=47300)
    parser.add_argument("--device-id", help="1..32 hex digits (default: from the key)")
    args = parser.parse_args()
    key = read_key(args.key_file)
    unique_id = (bytes.fromhex(args.device_id.rjust(32, "0")) if args.device_id
                 else default_device_id(key))
    data = block(key, args.device_ip, args.netmask, args.host_ip,
                 bytes.fromhex(args.mac.replace(":", "")), args.port, unique_id, os.urandom(32))
    fd = os.open(args.out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


if __name__ == "__main__":
    main()
