"""Experimenter accounts and their logins (browser sessions and bearer tokens).

Shared by the API and the `exostudy user` command, so both create accounts the same
way.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta
from typing import Literal

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.security import (
    hash_password,
    needs_rehash,
    new_token,
    token_digest,
    verify_password,
)
from backend.db.models import AuthToken, User

USERNAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"
MIN_PASSWORD_LENGTH = 8

#: A browser session lasts a working day; a script's bearer token a month.
LIFETIMES: dict[str, timedelta] = {"session": timedelta(hours=12),
                                   "bearer": timedelta(days=30)}

TokenKind = Literal["session", "bearer"]


class AccountError(ValueError):
    """An account cannot be created as asked (the message says why)."""


def _aware(t: datetime) -> datetime:
    # SQLite hands back naive datetimes even for timezone=True columns; they are UTC.
    return t if t.tzinfo is not None else t.replace(tzinfo=UTC)


def create_user(session: Session, username: str, password: str) -> User:
    """Add an experimenter (not committed). Raises `AccountError` for a bad name, a
    short password or a name that exists."""
    if not re.fullmatch(USERNAME_PATTERN, username):
        raise AccountError(f"username: {username!r} must be 1-64 letters, digits, '.', '_' "
                           "or '-', starting with a letter or digit")
    if len(password) < MIN_PASSWORD_LENGTH:
        raise AccountError(f"password: must have at least {MIN_PASSWORD_LENGTH} characters")
    if session.scalars(select(User).where(User.username == username)).first() is not None:
        raise AccountError(f"username: {username!r} already exists")
    user = User(username=username, password_hash=hash_password(password), active=True)
    session.add(user)
    session.flush()
    return user


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
