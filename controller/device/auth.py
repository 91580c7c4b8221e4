"""Authentication of the device link: the shared key, sessions and the replay window.

Every packet of protocol version 2 ends with an HMAC-SHA256 tag over everything before
it, computed with a 32-byte key that only the host and the device hold. A packet that
fails the tag is dropped before it can change anything, so a process on the same
machine or network that can send datagrams still cannot lock the exoskeleton or feed the
worker samples. Authentic packets can be recorded and sent again, so each side also
keeps (see `PeerSessions`):

- the peer's session: a random 64-bit number each side draws when it starts, carried in
  every packet, with the receiver's session as the sender knows it. A packet addressed
  to another session of the receiver (one before a restart) is stale; a session of the
  peer seen before and replaced is never accepted again.
- a sliding window of the last 64 sequence numbers of the current peer session, as in
  IPsec (RFC 4303, section 3.4.3): a number already seen, or older than the window, is a
  replay.

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
WINDOW = 64  # sequence numbers remembered per peer session
RETIRED_MAX = 1024  # replaced peer sessions remembered (a restart each; oldest forgotten)
_SEQ_MODULUS = 1 << 32


class KeyFileError(ValueError):
    """The key file is missing, malformed, or readable by others."""


def tag(key: bytes, data: bytes | memoryview) -> bytes:
    """HMAC-SHA256 of `data` under `key` (32 bytes)."""
    return hmac.new(key, data, hashlib.sha256).digest()


def verify(key: bytes, data: bytes | memoryview, received: bytes | memoryview) -> bool:
    """Whether `received` is the tag of `data`, compared in constant time."""
    return hmac.compare_digest(tag(key, data), bytes(received))


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


class ReplayWindow:
    """Which of the last `WINDOW` uint32 sequence numbers were seen (RFC 4303 style).

    `accept` says whether a number is new, and marks it. Order is serial arithmetic
    (RFC 1982), so the window works across the 2^32 wrap.
    """

    def __init__(self, size: int = WINDOW) -> None:
        self.size = size
        self.top: int | None = None
        self.bits = 0  # bit i: top - i was seen

    def accept(self, seq: int) -> bool:
        """True if `seq` was not seen and is inside the window; it is then marked."""
        if self.top is None:
            self.top, self.bits = seq, 1
            return True
        d = (seq - self.top) % _SEQ_MODULUS
        if d and d < _SEQ_MODULUS // 2:  # newer: slide the window up
            self.bits = ((self.bits << d) | 1) & ((1 << self.size) - 1) if d < self.size else 1
            self.top = seq
            return True
        back = (self.top - seq) % _SEQ_MODULUS
        if back >= self.size or (self.bits >> back) & 1:
            return False
        self.bits |= 1 << back
        return True


class PeerSessions:
    """The peer's current session, the sessions it had before, and the replay window.

    `check(session, seq, may_start)` returns "ok" (new number in the current session),
    "new" (a session never seen, now current; only if `may_start`), or "replay".
    """

    def __init__(self) -> None:
        self.current: int | None = None
        self.window = ReplayWindow()
        self._retired: dict[int, None] = {}  # insertion-ordered set

    def check(self, session: int, seq: int, may_start: bool = True) -> str:
        """Classify one authentic packet (see the class docstring)."""
        if session == self.current:
            return "ok" if self.window.accept(seq) else "replay"
        if session in self._retired or not may_start or session == 0:
            return "replay"
        if self.current is not None:
            self._retired[self.current] = None
            if len(self._retired) > RETIRED_MAX:
                del self._retired[next(iter(self._retired))]
        self.current = session
        self.window = ReplayWindow()
        self.window.accept(seq)
        return "new"
