"""Experimenter accounts and their logins (browser sessions and bearer tokens).

Shared by the API and the `exostudy user` command, so both create accounts the same
way.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta
from typing import Literal

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from backend.core.security import (
    hash_password,
    needs_rehash,
    new_token,
    token_digest,
    verify_password,
)
from backend.db.models import AuthToken, LoginFailure, User
from backend.study import password_policy

USERNAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"

#: Login throttling: at most this many failures per account, and per address, within
#: `THROTTLE_WINDOW`; then 429 until the oldest failure leaves the window. NIST SP
#: 800-63B asks for at most 100 consecutive failures per account; 10 per quarter hour
#: still lets a person mistype several times and costs a guesser 40 tries an hour.
THROTTLE_WINDOW = timedelta(minutes=15)
MAX_FAILURES_PER_ACCOUNT = 10
MAX_FAILURES_PER_ADDRESS = 50

#: A browser session lasts a working day; a script's bearer token a month.
LIFETIMES: dict[str, timedelta] = {"session": timedelta(hours=12),
                                   "bearer": timedelta(days=30)}

TokenKind = Literal["session", "bearer"]


class AccountError(ValueError):
    """An account cannot be created as asked (the message says why)."""


def _aware(t: datetime) -> datetime:
    # SQLite hands back naive datetimes even for timezone=True columns; they are UTC.
    return t if t.tzinfo is not None else t.replace(tzinfo=UTC)


def check_password(password: str, username: str) -> None:
    """Raise `AccountError` if the password policy refuses `password`."""
    why = password_policy.problem(password, username)
    if why is not None:
        raise AccountError(f"password: {why}")


def create_user(session: Session, username: str, password: str, role: str | None = None,
                *, published: bool = False) -> User:
    """Add an account (not committed). Raises `AccountError` for a bad name, a password
    the policy refuses or a name that exists.

    `role` None: the first account of a database is its administrator (someone must
    be able to manage the others), later ones are members. `published`: the password
    is printed somewhere public (the demo's); it skips the policy and is flagged so the
    server warns and refuses a non-loopback host until it is changed."""
    if not re.fullmatch(USERNAME_PATTERN, username):
        raise AccountError(f"username: {username!r} must be 1-64 letters, digits, '.', '_' "
                           "or '-', starting with a letter or digit")
    if not published:
        check_password(password, username)
    if role is not None and role not in ("admin", "member"):
        raise AccountError(f"role: {role!r} must be admin or member")
    if session.scalars(select(User).where(User.username == username)).first() is not None:
        raise AccountError(f"username: {username!r} already exists")
    if role is None:
        role = "member" if session.scalars(select(User.id)).first() is not None else "admin"
    user = User(username=username, password_hash=hash_password(password), active=True,
                role=role, password_published=published)
    session.add(user)
    session.flush()
    return user


def change_password(session: Session, user: User, new_password: str) -> None:
    """Set a new password (policy checked); the caller decides which logins end."""
    check_password(new_password, user.username)
    user.password_hash = hash_password(new_password)
    user.password_published = False
    session.flush()


def revoke_all(session: Session, user: User, keep: AuthToken | None = None) -> int:
    """End every login of `user` (except `keep`); returns how many were ended."""
    now = datetime.now(UTC)
    rows = session.scalars(select(AuthToken).where(
        AuthToken.user_id == user.id, AuthToken.revoked_at.is_(None)))
    n = 0
    for row in rows:
        if keep is None or row.id != keep.id:
            row.revoked_at = now
            n += 1
    session.flush()
    return n


def set_active(session: Session, user: User, active: bool) -> None:
    """Disable (every login ends) or re-enable an account."""
    user.active = active
    if not active:
        revoke_all(session, user)
    session.flush()


def published_password_accounts(session: Session) -> list[str]:
    """Active accounts whose password is still a published one (the demo's)."""
    return list(session.scalars(select(User.username).where(
        User.password_published.is_(True), User.active.is_(True))))


def throttled_for(session: Session, username: str, address: str) -> int | None:
    """Seconds to wait before this account or address may try again, or None."""
    now = datetime.now(UTC)
    since = now - THROTTLE_WINDOW
    waits = []
    for column, value, limit in ((LoginFailure.username, username, MAX_FAILURES_PER_ACCOUNT),
                                 (LoginFailure.address, address, MAX_FAILURES_PER_ADDRESS)):
        times = list(session.scalars(select(LoginFailure.at).where(
            column == value, LoginFailure.at > since).order_by(LoginFailure.at.desc())
            .limit(limit)))
        if len(times) >= limit:
            waits.append((_aware(times[-1]) + THROTTLE_WINDOW - now).total_seconds())
    return max(1, int(max(waits)) + 1) if waits else None


def record_failure(session: Session, username: str, address: str) -> None:
    """Remember a failed login (not committed); failures older than a day are dropped
    (the audit log keeps them)."""
    now = datetime.now(UTC)
    session.execute(delete(LoginFailure).where(LoginFailure.at < now - timedelta(days=1)))
    session.add(LoginFailure(at=now, username=username[:64], address=address[:64]))
    session.flush()


def authenticate(session: Session, username: str, password: str) -> User | None:
    """The active user with this name and password, or None (same cost either way)."""
    user = session.scalars(select(User).where(User.username == username)).first()
    ok = verify_password(user.password_hash if user else None, password)
    if user is None or not ok or not user.active:
        return None
    if needs_rehash(user.password_hash):
        user.password_hash = hash_password(password)
    return user


def issue_token(session: Session, user: User, kind: TokenKind) -> tuple[str, AuthToken]:
    """A new login for `user`; returns the token (shown once) and its row."""
    token = new_token()
    now = datetime.now(UTC)
    row = AuthToken(user_id=user.id, token_hash=token_digest(token), kind=kind,
                    created_at=now, expires_at=now + LIFETIMES[kind])
    session.add(row)
    session.flush()
    return token, row


def resolve_token(session: Session, token: str) -> tuple[User, AuthToken] | None:
    """The user and login behind a token, if it is valid, unexpired and not revoked."""
    row = session.scalars(
        select(AuthToken).where(AuthToken.token_hash == token_digest(token))).first()
    if row is None or row.revoked_at is not None:
        return None
    if _aware(row.expires_at) <= datetime.now(UTC):
        return None
    user = session.get(User, row.user_id)
    if user is None or not user.active:
        return None
    return user, row
