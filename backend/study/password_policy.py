"""What a new password must satisfy, following NIST SP 800-63B (revision 4).

- At least 15 characters: SP 800-63B-4 section 3.1.1.2 asks for 15 when the password
  is the only authenticator, as it is here. At most 1024 (the API's field bound; NIST
  asks to allow at least 64).
- Not a commonly used or compromised value: the list in `passwords/common.txt`
  (its sources are named in the file), also with digits or symbols appended, repeated,
  or with spaces; plus the context words NIST names (the service's and the account's
  names).
- Not a run: one short unit repeated ("        ", "abcabcabc...") or a keyboard or
  digit sequence.

No composition rules (NIST advises against them) and no forced periodic changes.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

MIN_LENGTH = 15
MAX_LENGTH = 1024
_LIST = Path(__file__).parent / "passwords" / "common.txt"
_RUNS = ("0123456789" * 3, "9876543210" * 3, "qwertyuiopasdfghjklzxcvbnm" * 2,
         "abcdefghijklmnopqrstuvwxyz" * 2)


@lru_cache(maxsize=1)
def common_passwords() -> frozenset[str]:
    """The refused values, lower case."""
    lines = _LIST.read_text(encoding="utf-8").splitlines()
    return frozenset(x.strip().lower() for x in lines if x.strip() and not x.startswith("#"))


def _repeats_a_short_unit(s: str) -> bool:
    return any(len(s) % n == 0 and s == s[:n] * (len(s) // n) for n in range(1, 5))


def _core(s: str) -> str:
    """Lower case, without whitespace, without trailing digits and symbols."""
    squeezed = re.sub(r"\s+", "", s.lower())
    return re.sub(r"[\d\W_]+$", "", squeezed) or squeezed


def _made_of(core: str, words: frozenset[str]) -> bool:
    """True if `core` is one refused word, possibly repeated ("passwordpassword")."""
    return any(w and len(core) % len(w) == 0 and core == w * (len(core) // len(w))
               for w in words)


def problem(password: str, username: str = "") -> str | None:
    """Why `password` is refused, or None if it is acceptable."""
    if len(password) < MIN_LENGTH:
        return f"must have at least {MIN_LENGTH} characters (NIST SP 800-63B)"
    if len(password) > MAX_LENGTH:
        return f"must have at most {MAX_LENGTH} characters"
    if not password.strip():
        return "must not be only spaces"
    if _repeats_a_short_unit(password):
        return "must not repeat one short sequence"
    squeezed = re.sub(r"\s+", "", password.lower())
    if any(squeezed in run for run in _RUNS):
        return "must not be a keyboard or number sequence"
    words = common_passwords() | {w for w in (username.lower(), "exostudy") if w}
    if squeezed in words or _made_of(_core(password), words):
        return "is a commonly used password (or built from one); choose another"
    return None
