"""Logging in and out: a session cookie for the browser, a bearer token for scripts."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from fastapi import APIRouter, HTTPException, Request, Response

from backend import accounts, audit
from backend.api.deps import SESSION_COOKIE, CurrentLogin, CurrentUser, SessionDep
from backend.api.errors import AUTH_RESPONSES, BODY, ErrorMessage
from backend.schemas.auth import Credentials, LoginOut, TokenOut, UserOut

router = APIRouter(prefix="/api/auth", tags=["auth"])

_BAD_LOGIN: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorMessage, "description": "wrong username or password"}}


def _login(db: SessionDep, creds: Credentials, kind: accounts.TokenKind
           ) -> tuple[str, datetime, UserOut]:
    user = accounts.authenticate(db, creds.username, creds.password)
    if user is None:
        # One message for both cases: which accounts exist is not the caller's business.
        raise HTTPException(401, "username or password is wrong")
    token, row = accounts.issue_token(db, user, kind)
    audit.record(db, user, "login", "user", user.id, {"kind": kind})
    db.commit()
    return token, row.expires_at, UserOut.model_validate(user)


@router.post("/login", response_model=LoginOut, responses={**_BAD_LOGIN, **BODY})
def login(creds: Credentials, db: SessionDep, request: Request, response: Response
          ) -> LoginOut:
    """Log in from a browser: sets the httponly session cookie."""
    token, expires, user = _login(db, creds, "session")
    response.set_cookie(
        SESSION_COOKIE, token, httponly=True, samesite="strict", path="/",
        secure=request.url.scheme == "https",
        max_age=int((expires - datetime.now(UTC)).total_seconds()),
    )
    return LoginOut(user=user, expires_at=expires)


@router.post("/token", response_model=TokenOut, responses={**_BAD_LOGIN, **BODY})
def token(creds: Credentials, db: SessionDep) -> TokenOut:
    """Log in from a script: returns a bearer token (`Authorization: Bearer ...`)."""
    tok, expires, user = _login(db, creds, "bearer")
    return TokenOut(access_token=tok, expires_at=expires, user=user)


@router.post("/logout", status_code=204, responses=AUTH_RESPONSES)
def logout(login: CurrentLogin, db: SessionDep) -> Response:
    """End this login (the cookie's or the bearer token's); other logins stay."""
    user, row = login
    row.revoked_at = datetime.now(UTC)
    audit.record(db, user, "logout", "user", user.id, {"kind": row.kind})
    db.commit()
    response = Response(status_code=204)
    response.delete_cookie(SESSION_COOKIE, path="/")
    return response


@router.get("/me", response_model=UserOut, responses=AUTH_RESPONSES)
def me(user: CurrentUser) -> UserOut:
    """Who is logged in."""
    return UserOut.model_validate(user)
