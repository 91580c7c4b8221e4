"""Secrets: argon2 password hashes and random tokens that are stored only as digests.

Tokens (login sessions, participant links) are 256-bit random strings; the database
keeps their SHA-256, which is enough for lookup and useless to someone who copies the
file. A fast hash is right here because the token itself is unguessable; passwords are
not, so they get argon2.
"""

from __future__ import annotations

import functools
import hashlib
import secrets

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

_hasher = PasswordHasher()


@functools.cache
def _dummy_hash() -> str:
    """A hash to verify against when the username does not exist, so that a wrong
    username takes as long as a wrong password and does not reveal which accounts exist.
    Made on first use, not at import: an argon2 hash costs every process that imports
    this module (the server, each CLI command, each test process) 0.3-0.5 s of CPU."""
    return _hasher.hash("exostudy-no-such-user")


def hash_password(password: str) -> str:
    """The argon2id hash (with its own salt and parameters) to store."""
    return _hasher.hash(password)


def verify_password(password_hash: str | None, password: str) -> bool:
    """True if `password` matches; a missing hash still costs one verification."""
    try:
        return _hasher.verify(password_hash or _dummy_hash(), password) and bool(password_hash)
    except (VerificationError, InvalidHashError):
        return False


def needs_rehash(password_hash: str) -> bool:
    """True when the hash was made with older argon2 parameters than today's."""
    return _hasher.check_needs_rehash(password_hash)


def new_token() -> str:
    """A fresh URL-safe random token (256 bits)."""
    return secrets.token_urlsafe(32)


def token_digest(token: str) -> str:
    """What the database stores for a token."""
    return hashlib.sha256(token.encode("utf-8")).hexdigest()
