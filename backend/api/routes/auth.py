"""Logging in and out (a session cookie for the browser, a bearer token for scripts),
changing one's password, ending every login, and the accounts an admin manages."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path, Request, Response
from sqlalchemy import select

from backend.api.deps import (
    SESSION_COOKIE,
    CurrentLogin,
    CurrentUser,
    SessionDep,
    SettingsDep,
    SocketLoginsDep,
    access,
)
from backend.api.errors import AUTH_RESPONSES, BODY, CONFLICT, ErrorMessage, invalid, not_found
from backend.api.params import MAX_ID
from backend.api.web_surface import CSRF_COOKIE, csrf_token_for
from backend.db import audit
from backend.db.models import User
from backend.schemas.auth import (
    AccountUpdate,
    Credentials,
    LoginOut,
    Me,
    NewAccount,
    PasswordChange,
    TokenOut,
    UserOut,
)
from backend.study import accounts

router = APIRouter(prefix="/api/auth", tags=["auth"])
users = APIRouter(prefix="/api/users", tags=["accounts"], responses=AUTH_RESPONSES)

_BAD_LOGIN: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorMessage, "description": "wrong username or password"},
    429: {"model": ErrorMessage, "description": "too many failed logins for this account "
          "or address; `Retry-After` says how many seconds to wait"}}


def _address(request: Request) -> str:
    return request.client.host if request.client else "unknown"


def _login(db: SessionDep, request: Request, creds: Credentials, kind: accounts.TokenKind
           ) -> tuple[str, datetime, UserOut]:
    address = _address(request)
    # Counted and committed before the (slow) password check: attempts sent together
    # each take their own place under the limit (backend/study/accounts.py).
    wait = accounts.take_attempt(db, creds.username, address)
    if wait is not None:
        audit.record(db, "login throttle", "login_throttled", "user", None,
                     {"username": creds.username[:64], "address": address})
        db.commit()
        raise HTTPException(429, f"username: too many failed logins; try again in {wait} s",
                            headers={"Retry-After": str(wait)})
    db.commit()
    user = accounts.authenticate(db, creds.username, creds.password)
    if user is None:
        accounts.record_failure(db, creds.username, address)
        audit.record(db, "login attempt", "login_failed", "user", None,
                     {"username": creds.username[:64], "address": address})
        db.commit()
        # One message for both cases: which accounts exist is not the caller's business.
        raise HTTPException(401, "username or password is wrong")
    accounts.give_back_attempt(db, creds.username, address)
    token, row = accounts.issue_token(db, user, kind)
    audit.record(db, user, "login", "user", user.id, {"kind": kind, "address": address})
    db.commit()
    return token, row.expires_at, UserOut.model_validate(user)


@router.post("/login", response_model=LoginOut, responses={**_BAD_LOGIN, **BODY},
             openapi_extra=access("public"))
def login(creds: Credentials, db: SessionDep, request: Request, response: Response,
          settings: SettingsDep) -> LoginOut:
    """Log in from a browser: sets the httponly session cookie and the CSRF cookie
    (whose value the pages send as `X-CSRF-Token` with every change)."""
    token, expires, user = _login(db, request, creds, "session")
    secure = settings.secure_cookies or request.url.scheme == "https"
    max_age = int((expires - datetime.now(UTC)).total_seconds())
    response.set_cookie(SESSION_COOKIE, token, httponly=True, samesite="strict", path="/",
                        secure=secure, max_age=max_age)
    response.set_cookie(CSRF_COOKIE, csrf_token_for(token), httponly=False,
                        samesite="strict", path="/", secure=secure, max_age=max_age)
    return LoginOut(user=user, expires_at=expires)


@router.post("/token", response_model=TokenOut, responses={**_BAD_LOGIN, **BODY},
             openapi_extra=access("public"))
def token(creds: Credentials, db: SessionDep, request: Request) -> TokenOut:
    """Log in from a script: returns a bearer token (`Authorization: Bearer ...`)."""
    tok, expires, user = _login(db, request, creds, "bearer")
    return TokenOut(access_token=tok, expires_at=expires, user=user)


def _forget_cookies(response: Response) -> None:
    response.delete_cookie(SESSION_COOKIE, path="/")
    response.delete_cookie(CSRF_COOKIE, path="/")


@router.post("/logout", status_code=204, responses=AUTH_RESPONSES,
             openapi_extra=access("login"))
def logout(login: CurrentLogin, db: SessionDep, sockets: SocketLoginsDep) -> Response:
    """End this login (the cookie's or the bearer token's) and the WebSockets opened
    with it; other logins stay."""
    user, row = login
    row.revoked_at = datetime.now(UTC)
    audit.record(db, user, "logout", "user", user.id, {"kind": row.kind})
    db.commit()
    sockets.logins_changed(user.id)
    response = Response(status_code=204)
    _forget_cookies(response)
    return response


@router.post("/revoke-all", status_code=204, responses=AUTH_RESPONSES,
             openapi_extra=access("login"))
def revoke_all(login: CurrentLogin, db: SessionDep, sockets: SocketLoginsDep) -> Response:
    """End every login of this account, this one included (a lost laptop, a leaked
    token), and every WebSocket opened with them."""
    user, _ = login
    n = accounts.revoke_all(db, user)
    audit.record(db, user, "revoke_all", "user", user.id, {"logins": n})
    db.commit()
    sockets.logins_changed(user.id)
    response = Response(status_code=204)
    _forget_cookies(response)
    return response


@router.post("/password", status_code=204, responses={**AUTH_RESPONSES, **BODY},
             openapi_extra=access("login"))
def change_password(body: PasswordChange, login: CurrentLogin, db: SessionDep,
                    sockets: SocketLoginsDep) -> Response:
    """Change one's own password; every other login of the account ends."""
    user, row = login
    if not accounts.authenticate(db, user.username, body.current_password):
        invalid(["body", "current_password"], "is wrong")
    try:
        accounts.change_password(db, user, body.new_password)
    except accounts.AccountError as exc:
        invalid(["body", "new_password"], str(exc).removeprefix("password: "))
    accounts.revoke_all(db, user, keep=row)
    audit.record(db, user, "change_password", "user", user.id, {})
    db.commit()
    sockets.logins_changed(user.id)
    return Response(status_code=204)


@router.get("/me", response_model=Me, responses=AUTH_RESPONSES, openapi_extra=access("login"))
def me(user: CurrentUser, db: SessionDep) -> Me:
    """Who is logged in, and the warnings every page shows."""
    return Me(**UserOut.model_validate(user).model_dump(),
              published_login_accounts=accounts.published_password_accounts(db))


# --- Accounts (admin) ------------------------------------------------------------------


@users.get("", response_model=list[UserOut], openapi_extra=access("admin"))
def list_users(db: SessionDep) -> list[User]:
    """Every account, by name."""
    return list(db.scalars(select(User).order_by(User.username)))


@users.post("", response_model=UserOut, status_code=201, responses={**BODY, **CONFLICT},
            openapi_extra=access("admin"))
def add_user(body: NewAccount, admin: CurrentUser, db: SessionDep) -> User:
    """Create an account (the password policy applies)."""
    try:
        user = accounts.create_user(db, body.username, body.password, body.role)
    except accounts.AccountError as exc:
        field, _, problem = str(exc).partition(": ")
        if "already exists" in problem:
            raise HTTPException(409, str(exc)) from exc
        invalid(["body", field], problem)
    audit.record(db, admin, "create", "user", user.id,
                 {"username": user.username, "role": user.role})
    db.commit()
    return user


@users.patch("/{user_id}", response_model=UserOut, responses=BODY,
             openapi_extra=access("admin"))
def update_user(user_id: Annotated[int, Path(ge=1, le=MAX_ID, description="account id")],
                body: AccountUpdate, admin: CurrentUser, db: SessionDep,
                sockets: SocketLoginsDep) -> User:
    """Change an account's role, disable or enable it (disabling ends its logins), or
    set a new password (its logins end)."""
    user = db.get(User, user_id)
    if user is None:
        not_found("user", user_id)
    changes: dict[str, Any] = {}
    if body.password is not None:
        try:
            accounts.change_password(db, user, body.password)
        except accounts.AccountError as exc:
            invalid(["body", "password"], str(exc).removeprefix("password: "))
        accounts.revoke_all(db, user)
        changes["password"] = "changed"
    if body.role is not None and body.role != user.role:
        if user.id == admin.id:
            invalid(["body", "role"], "you cannot remove your own admin role")
        user.role = body.role
        changes["role"] = body.role
    if body.active is not None and body.active != user.active:
        if user.id == admin.id and not body.active:
            invalid(["body", "active"], "you cannot disable your own account")
        accounts.set_active(db, user, body.active)
        changes["active"] = body.active
    audit.record(db, admin, "update", "user", user.id, changes)
    db.commit()
    sockets.logins_changed(user.id)  # disabled, or logins ended by a new password
    return user
