"""Authentication of the device link: the shared key, its public name, and sessions.

Every packet of the protocol ends with an HMAC-SHA256 tag over everything before it,
computed with a 32-byte key that only the host and the device hold. A packet that fails
the tag is dropped before it can change anything, so a process on the same machine or
network that can send datagrams still cannot lock the exoskeleton or feed the worker
samples. Authentic packets can be recorded and sent again; version 3 makes that useless
without any memory of old sessions (docs/device-protocol.md, "Threat model"): a host
session opens only by answering the device's single-use challenge, and a command counts
only against a sample the device sent less than 100 ms earlier. So this module keeps no
replay window and no list of retired sessions: there is nothing an attacker can overflow.

The key file holds the key as 64 hexadecimal digits. It is created at first start with
mode 0600 (owner read/write only) and refused if anyone else may read it.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
import stat
from pathlib import Path

KEY_BYTES = 32
TAG_BYTES = 32
KEY_ID_BYTES = 8  # the key id: this many bytes of HMAC(key, KEY_ID_LABEL), as hex
KEY_ID_LABEL = b"exostudy key id"
UNIQUE_ID_BYTES = 16
SIMULATED_ID_LABEL = b"exostudy simulated device"


class KeyFileError(ValueError):
    """The key file is missing, malformed, or readable by others."""


def tag(key: bytes, data: bytes | memoryview) -> bytes:
    """HMAC-SHA256 of `data` under `key` (32 bytes)."""
    return hmac.new(key, data, hashlib.sha256).digest()


def verify(key: bytes, data: bytes | memoryview, received: bytes | memoryview) -> bool:
    """Whether `received` is the tag of `data`, compared in constant time."""
    return hmac.compare_digest(tag(key, data), bytes(received))


def key_id(key: bytes) -> str:
    """The key's public name (16 lowercase hex digits): names a key in hardware
    profiles, logs and the console without revealing it (HMAC is one-way)."""
    return tag(key, KEY_ID_LABEL)[:KEY_ID_BYTES].hex()


def simulated_unique_id(key: bytes) -> bytes:
    """The unique id both simulators (Python and C) report by default: derived from
    the key, so that a hardware profile follows the simulated device whichever
    implementation runs it, and differs between labs."""
    return tag(key, SIMULATED_ID_LABEL)[:UNIQUE_ID_BYTES]


def parse_unique_id(text: str) -> bytes:
    """A `--device-id` argument: 1..32 hex digits, zero-padded to 16 bytes (the digits
    first, as they are written)."""
    if not 1 <= len(text) <= 2 * UNIQUE_ID_BYTES or any(
            c not in "0123456789abcdefABCDEF" for c in text):
        raise ValueError(f"device id {text!r}: expected 1..{2 * UNIQUE_ID_BYTES} hex digits")
    if len(text) % 2:
        text += "0"
    return bytes.fromhex(text).ljust(UNIQUE_ID_BYTES, b"\0")


def new_session() -> int:
    """A random, non-zero 64-bit session number (0 means "not known yet" on the wire)."""
    while True:
        s = secrets.randbits(64)
        if s:
            return s


def create_key(path: Path) -> bytes:
    """Write a new random key to `path` (mode 0600, never over an existing file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    key = secrets.token_bytes(KEY_BYTES)
    # Written whole under a private name, then linked into place: a reader never sees
    # a half-written key, and two first starts cannot both win (link fails if it exists).
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(key.hex() + "\n")
        os.link(tmp, path)
    finally:
        tmp.unlink()
    return key


def load_key(path: Path) -> bytes:
    """The key in `path`; refused if the file is missing, malformed or not private."""
    try:
        st = path.stat()
    except FileNotFoundError:
        raise KeyFileError(f"{path}: no device key file") from None
    if st.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise KeyFileError(f"{path}: readable by others (mode {stat.S_IMODE(st.st_mode):o}); "
                           "chmod 600 it")
    text = path.read_text().strip()
    try:
        key = bytes.fromhex(text)
    except ValueError:
        raise KeyFileError(f"{path}: not hexadecimal") from None
    if len(key) != KEY_BYTES:
        raise KeyFileError(f"{path}: the key must be {KEY_BYTES} bytes "
                           f"({2 * KEY_BYTES} hex digits), got {len(key)}")
    return key


def load_or_create_key(path: Path) -> bytes:
    """The key in `path`, created there first if there is none."""
    try:
        return create_key(path)
    except FileExistsError:
        return load_key(path)
