"""Experimenter accounts and their logins (browser sessions and bearer tokens).

Shared by the API and the `exostudy user` command, so both create accounts the same
way.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta
from typing import Literal

from sqlalchemy import case, delete, or_, select, update
from sqlalchemy.dialects.postgresql import insert as postgresql_insert
from sqlalchemy.dialects.sqlite import insert as sqlite_insert
from sqlalchemy.orm import Session

from backend.core.security import (
    hash_password,
    needs_rehash,
    new_token,
    token_digest,
    verify_password,
)
from backend.db.models import AuthToken, LoginFailure, LoginThrottle, User
from backend.study import password_policy

USERNAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"

#: Login throttling: at most this many attempts per account, and per address, within a
#: `THROTTLE_WINDOW` that starts with the first; then 429 until it ends. An attempt is
#: counted before its password is checked and a successful one is given back, so the
#: limit counts failures and holds for attempts sent all at once. NIST SP
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


def _throttle_keys(username: str, address: str) -> list[tuple[str, int]]:
    return [(f"account:{username[:64]}", MAX_FAILURES_PER_ACCOUNT),
            (f"address:{address[:64]}", MAX_FAILURES_PER_ADDRESS)]


def _take(session: Session, key: str, limit: int, now: datetime) -> int | None:
    """Count one attempt for `key` if its window has room (or has ended: a new window
    starts now); else the seconds until the window ends. One conditional UPDATE, which
    the database runs one at a time per row (a row lock on PostgreSQL, the write lock
    on SQLite), so `limit` attempts pass however many arrive together."""
    t = LoginThrottle
    insert = postgresql_insert if session.get_bind().dialect.name == "postgresql" \
        else sqlite_insert
    session.execute(insert(t).values(key=key, window_start=now, attempts=0)
                    .on_conflict_do_nothing(index_elements=["key"]))
    ended = t.window_start <= now - THROTTLE_WINDOW
    counted = session.execute(
        update(t).where(t.key == key, or_(ended, t.attempts < limit))
        .values(attempts=case((ended, 1), else_=t.attempts + 1),
                window_start=case((ended, now), else_=t.window_start))
        .execution_options(synchronize_session=False))
    if getattr(counted, "rowcount", 0) == 1:
        return None
    start = session.scalars(select(t.window_start).where(t.key == key)).one()
    return max(1, int((_aware(start) + THROTTLE_WINDOW - now).total_seconds()) + 1)


def take_attempt(session: Session, username: str, address: str) -> int | None:
    """Count a login attempt against the account and the address before the password
    is checked (not committed: the caller commits at once, so that concurrent attempts
    see it). None: go ahead; else the seconds to wait, and nothing was counted."""
    now = datetime.now(UTC)
    taken: list[str] = []
    for key, limit in _throttle_keys(username, address):
        wait = _take(session, key, limit, now)
        if wait is not None:
            for k in taken:
                _give_back(session, k)
            return wait
        taken.append(key)
    return None


def _give_back(session: Session, key: str) -> None:
    t = LoginThrottle
    session.execute(update(t).where(t.key == key, t.attempts > 0)
                    .values(attempts=t.attempts - 1)
                    .execution_options(synchronize_session=False))


def give_back_attempt(session: Session, username: str, address: str) -> None:
    """A successful login does not count against the limits (not committed)."""
    for key, _ in _throttle_keys(username, address):
        _give_back(session, key)


def record_failure(session: Session, username: str, address: str) -> None:
    """Remember a failed login (not committed; its attempt is already counted); failures
    and throttle windows older than a day are dropped (the audit log keeps them)."""
    now = datetime.now(UTC)
    session.execute(delete(LoginFailure).where(LoginFailure.at < now - timedelta(days=1)))
    session.execute(delete(LoginThrottle).where(
        LoginThrottle.window_start < now - timedelta(days=1)))
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
