"""Dependencies shared by the routes (FastAPI `Annotated` aliases)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, HTTPException, Request
from fastapi.security import APIKeyCookie, HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session, sessionmaker

from backend.accounts import resolve_token
from backend.db.models import AuthToken, User
from backend.runtime import Runtime

#: Name of the httponly cookie that carries a browser's login.
SESSION_COOKIE = "exostudy_session"

# auto_error=False: a missing credential is answered by `current_login` with one
# consistent 401, and both schemes still appear in the OpenAPI schema.
_bearer = HTTPBearer(auto_error=False, description="a token from POST /api/auth/token")
_cookie = APIKeyCookie(name=SESSION_COOKIE, auto_error=False,
                       description="set by POST /api/auth/login")


def get_runtime(request: Request) -> Runtime:
    """The server's live path (created by the lifespan)."""
    runtime: Runtime = request.app.state.runtime
    return runtime


RuntimeDep = Annotated[Runtime, Depends(get_runtime)]


def get_db(request: Request) -> Iterator[Session]:
    """A database session per request. Routes commit once, at the end of a write, so a
    request that fails half-way leaves nothing behind (closing rolls back)."""
    factory: sessionmaker[Session] = request.app.state.sessions
    with factory() as session:
        yield session


SessionDep = Annotated[Session, Depends(get_db)]


def login_from_token(sessions: sessionmaker[Session], token: str | None
                     ) -> tuple[User, AuthToken] | None:
    """The login a raw token belongs to, for callers outside a request's dependencies
    (the WebSocket and the pages)."""
    if not token:
        return None
    with sessions() as session:
        return resolve_token(session, token)


def current_login(
    db: SessionDep,
    bearer: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    cookie: Annotated[str | None, Depends(_cookie)],
) -> tuple[User, AuthToken]:
    """The logged-in experimenter and the login used (bearer token first, then cookie);
    401 otherwise."""
    for token in (bearer.credentials if bearer else None, cookie):
        if token:
            found = resolve_token(db, token)
            if found is not None:
                return found
    raise HTTPException(401, "not logged in: POST /api/auth/login (cookie) or "
                        "/api/auth/token (bearer)", headers={"WWW-Authenticate": "Bearer"})


CurrentLogin = Annotated[tuple[User, AuthToken], Depends(current_login)]


def current_user(login: CurrentLogin) -> User:
    """The logged-in experimenter."""
    return login[0]


CurrentUser = Annotated[User, Depends(current_user)]
