"""Logging in and out (a session cookie for the browser, a bearer token for scripts),
changing one's password, ending every login, and the accounts an admin manages."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path, Request, Response

from backend.api.deps import (
    SESSION_COOKIE,
    CurrentLogin,
    CurrentUser,
    SessionDep,
    SettingsDep,
    SocketLoginsDep,
    access,
)
from backend.api.errors import AUTH_RESPONSES, BODY, CONFLICT, ErrorMessage
from backend.api.params import MAX_ID
from backend.api.web_surface import CSRF_COOKIE, csrf_token_for
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
from backend.study import accounts, logins

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
    try:
        token, row, user = logins.login(db, creds.username, creds.password, _address(request),
                                        kind)
    except logins.LoginThrottledError as exc:
        raise HTTPException(429, str(exc), headers={"Retry-After": str(exc.wait)}) from None
    except logins.LoginRefusedError as exc:
        raise HTTPException(401, str(exc)) from None
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
    logins.logout(db, user, row)
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
    logins.revoke_all(db, user)
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
    logins.change_password(db, user, row, body.current_password, body.new_password)
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
    return logins.users(db)


@users.post("", response_model=UserOut, status_code=201, responses={**BODY, **CONFLICT},
            openapi_extra=access("admin"))
def add_user(body: NewAccount, admin: CurrentUser, db: SessionDep) -> User:
    """Create an account (the password policy applies)."""
    return logins.add_user(db, admin, body)


@users.patch("/{user_id}", response_model=UserOut, responses=BODY,
             openapi_extra=access("admin"))
def update_user(user_id: Annotated[int, Path(ge=1, le=MAX_ID, description="account id")],
                body: AccountUpdate, admin: CurrentUser, db: SessionDep,
                sockets: SocketLoginsDep) -> User:
    """Change an account's role, disable or enable it (disabling ends its logins), or
    set a new password (its logins end)."""
    user = logins.update_user(db, admin, user_id, body)
    sockets.logins_changed(user.id)  # disabled, or logins ended by a new password
    return user
