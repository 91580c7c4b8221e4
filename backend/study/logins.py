"""Logging in and out, changing a password, and the accounts an admin manages: the
writes and audit rows behind `/api/auth` and `/api/users`, on top of the account rules
in `backend.study.accounts`. The routes set cookies and answer; this module decides."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError
from backend.db import audit
from backend.db.models import AuthToken, User
from backend.schemas.auth import AccountUpdate, NewAccount
from backend.study import accounts


class LoginThrottledError(Exception):
    """Too many failed logins for the account or the address: wait `wait` seconds."""

    def __init__(self, wait: int) -> None:
        super().__init__(f"username: too many failed logins; try again in {wait} s")
        self.wait = wait


class LoginRefusedError(Exception):
    """Wrong username or password (one message for both: which accounts exist is not
    the caller's business)."""

    def __init__(self) -> None:
        super().__init__("username or password is wrong")


def login(db: Session, username: str, password: str, address: str,
          kind: accounts.TokenKind) -> tuple[str, AuthToken, User]:
    """A new login token for a correct username and password from `address`."""
    # Counted and committed before the (slow) password check: attempts sent together
    # each take their own place under the limit (backend/study/accounts.py).
    wait = accounts.take_attempt(db, username, address)
    if wait is not None:
        audit.record(db, "login throttle", "login_throttled", "user", None,
                     {"username": username[:64], "address": address})
        db.commit()
        raise LoginThrottledError(wait)
    db.commit()
    user = accounts.authenticate(db, username, password)
    if user is None:
        accounts.record_failure(db, username, address)
        audit.record(db, "login attempt", "login_failed", "user", None,
                     {"username": username[:64], "address": address})
        db.commit()
        raise LoginRefusedError()
    accounts.give_back_attempt(db, username, address)
    token, row = accounts.issue_token(db, user, kind)
    audit.record(db, user, "login", "user", user.id, {"kind": kind, "address": address})
    db.commit()
    return token, row, user


def logout(db: Session, user: User, row: AuthToken) -> None:
    """End this one login."""
    row.revoked_at = datetime.now(UTC)
    audit.record(db, user, "logout", "user", user.id, {"kind": row.kind})
    db.commit()


def revoke_all(db: Session, user: User) -> None:
    """End every login of the account."""
    n = accounts.revoke_all(db, user)
    audit.record(db, user, "revoke_all", "user", user.id, {"logins": n})
    db.commit()


def _new_password(db: Session, user: User, password: str, field: str) -> None:
    try:
        accounts.change_password(db, user, password)
    except accounts.AccountError as exc:
        raise InvalidError.at(["body", field], str(exc).removeprefix("password: ")) from exc


def change_password(db: Session, user: User, row: AuthToken, current: str, new: str) -> None:
    """One's own new password; every other login of the account ends."""
    if not accounts.authenticate(db, user.username, current):
        raise InvalidError.at(["body", "current_password"], "is wrong")
    _new_password(db, user, new, "new_password")
    accounts.revoke_all(db, user, keep=row)
    audit.record(db, user, "change_password", "user", user.id, {})
    db.commit()


def users(db: Session) -> list[User]:
    """Every account, by name."""
    return list(db.scalars(select(User).order_by(User.username)))


def add_user(db: Session, admin: User, body: NewAccount) -> User:
    """A new account (the password policy applies); a conflict if the name exists."""
    try:
        user = accounts.create_user(db, body.username, body.password, body.role)
    except accounts.AccountError as exc:
        field, _, problem = str(exc).partition(": ")
        if "already exists" in problem:
            raise ConflictError(field, problem) from exc
        raise InvalidError.at(["body", field], problem) from exc
    audit.record(db, admin, "create", "user", user.id,
                 {"username": user.username, "role": user.role})
    db.commit()
    return user


def update_user(db: Session, admin: User, user_id: int, body: AccountUpdate) -> User:
    """An account's role, enabled state or password changed (a new password or
    disabling ends its logins); an admin cannot demote or disable themselves."""
    user = db.get(User, user_id)
    if user is None:
        raise NotFoundError("user", user_id)
    changes: dict[str, Any] = {}
    if body.password is not None:
        _new_password(db, user, body.password, "password")
        accounts.revoke_all(db, user)
        changes["password"] = "changed"
    if body.role is not None and body.role != user.role:
        if user.id == admin.id:
            raise InvalidError.at(["body", "role"], "you cannot remove your own admin role")
        user.role = body.role
        changes["role"] = body.role
    if body.active is not None and body.active != user.active:
        if user.id == admin.id and not body.active:
            raise InvalidError.at(["body", "active"], "you cannot disable your own account")
        accounts.set_active(db, user, body.active)
        changes["active"] = body.active
    audit.record(db, admin, "update", "user", user.id, changes)
    db.commit()
    return user
