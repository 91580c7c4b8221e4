"""Dependencies shared by the routes (FastAPI `Annotated` aliases)."""

from __future__ import annotations

import re
import threading
from collections.abc import Iterator
from typing import Annotated, Any, Literal, NoReturn

from fastapi import Depends, FastAPI, HTTPException, Request, WebSocketException
from fastapi.routing import APIRoute, iter_route_contexts
from fastapi.security import APIKeyCookie, HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker
from starlette.requests import HTTPConnection
from starlette.routing import BaseRoute

from backend.analysis.jobs import JobRunner
from backend.analysis.results_cache import ResultsCache
from backend.api import web_surface
from backend.api.errors import not_found
from backend.api.params import path_id
from backend.api.socket_logins import SocketLogins
from backend.core.config import Settings
from backend.db.models import AuthToken, User
from backend.emg.live import EmgLab
from backend.lab.hub import Lab
from backend.live.runtime import Runtime
from backend.study import access as access_rules
from backend.study import device_grants
from backend.study.accounts import resolve_token

#: Name of the httponly cookie that carries a browser's login.
SESSION_COOKIE = "exostudy_session"

# auto_error=False: a missing credential is answered by `current_login` with one
# consistent 401, and both schemes still appear in the OpenAPI schema.
_bearer = HTTPBearer(auto_error=False, description="a token from POST /api/auth/token")
_cookie = APIKeyCookie(name=SESSION_COOKIE, auto_error=False,
                       description="set by POST /api/auth/login")


def get_runtime(conn: HTTPConnection) -> Runtime:
    """The server's live path (created by the lifespan); for requests and WebSockets."""
    runtime: Runtime = conn.app.state.runtime
    return runtime


RuntimeDep = Annotated[Runtime, Depends(get_runtime)]


def get_lab(conn: HTTPConnection) -> Lab:
    """The lab's LSL outlets, marker inlets and markers (created by the lifespan and
    attached to the live path, which feeds it)."""
    lab: Lab = conn.app.state.lab
    return lab


LabDep = Annotated[Lab, Depends(get_lab)]


def get_emg_lab(conn: HTTPConnection) -> EmgLab:
    """The EMG inlets (created by the lifespan, started and stopped with the live
    path)."""
    emg: EmgLab = conn.app.state.emg
    return emg


EmgLabDep = Annotated[EmgLab, Depends(get_emg_lab)]


def get_db(request: Request) -> Iterator[Session]:
    """A database session per request. Routes commit once, at the end of a write, so a
    request that fails half-way leaves nothing behind (closing rolls back)."""
    factory: sessionmaker[Session] = request.app.state.sessions
    with factory() as session:
        yield session


SessionDep = Annotated[Session, Depends(get_db)]


def get_settings_of_app(request: Request) -> Settings:
    """The settings the application was built with (not re-read from the environment)."""
    settings: Settings = request.app.state.settings
    return settings


SettingsDep = Annotated[Settings, Depends(get_settings_of_app)]


#: Requests holding the engine (reads of ticks beside the request's session) at once.
#: Each may hold two pooled connections (its session's and the read's); twelve hold at
#: most 24 of the pool's 30 (`backend.db.engine`), so they cannot wait on each other
#: for the pool, and the tick writer has a pool of its own (backend/main.py). Twelve is
#: more than the results page asks for at once (its tables, downloads and figures).
HEAVY_READS = 12
#: Seconds a refused heavy read is told to wait.
HEAVY_RETRY_S = 2


def heavy_reads_gate() -> threading.BoundedSemaphore:
    """The app's gate of `HEAVY_READS` (set on `app.state.heavy_reads`)."""
    return threading.BoundedSemaphore(HEAVY_READS)


def get_engine(request: Request) -> Iterator[Engine]:
    """The database engine, for reads that stream ticks outside the request's session;
    at most `HEAVY_READS` requests at once, others answered 503 with `Retry-After`
    (never left to wait for a pool connection while holding one)."""
    gate: threading.BoundedSemaphore | None = getattr(request.app.state, "heavy_reads",
                                                       None)
    if gate is not None and not gate.acquire(blocking=False):
        raise HTTPException(503, f"{HEAVY_READS} analysis or export requests are running; "
                            f"try again in {HEAVY_RETRY_S} s",
                            headers={"Retry-After": str(HEAVY_RETRY_S)})
    try:
        yield request.app.state.engine
    finally:
        if gate is not None:
            gate.release()


EngineDep = Annotated[Engine, Depends(get_engine)]


def get_session_factory(conn: HTTPConnection) -> sessionmaker[Session]:
    """The session factory, for work that outlives the request (background jobs, a
    WebSocket's login check)."""
    factory: sessionmaker[Session] = conn.app.state.sessions
    return factory


SessionFactoryDep = Annotated[sessionmaker[Session], Depends(get_session_factory)]


def get_socket_logins(conn: HTTPConnection) -> SocketLogins:
    """The open WebSockets' login watchers: routes that revoke logins wake them."""
    logins: SocketLogins = conn.app.state.socket_logins
    return logins


SocketLoginsDep = Annotated[SocketLogins, Depends(get_socket_logins)]


def get_jobs(request: Request) -> JobRunner:
    """The background job runner (model fitting, utilities, cohorts)."""
    jobs: JobRunner = request.app.state.jobs
    return jobs


JobsDep = Annotated[JobRunner, Depends(get_jobs)]


def get_results_cache(request: Request) -> ResultsCache:
    """The server's cache of recent study evaluations (one per application)."""
    cache: ResultsCache | None = getattr(request.app.state, "results_cache", None)
    if cache is None:
        cache = request.app.state.results_cache = ResultsCache()
    return cache


ResultsCacheDep = Annotated[ResultsCache, Depends(get_results_cache)]


def get_site(request: Request) -> str | None:
    """The site the caller's grant limits them to (None: every site), as the access
    check stored it for this request."""
    site: str | None = getattr(getattr(request.state, "grant", None), "site", None)
    return site


SiteDep = Annotated[str | None, Depends(get_site)]


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


# --- Authorisation: one dependency for every route -----------------------------------
# `authorize` is installed on the application (`FastAPI(dependencies=...)`), so every
# route, including ones added later, passes through it. A route states what it needs
# with `openapi_extra=access("owner")` (or another rule); without that, a path with an
# id the resolvers know (`study_id`, `participant_id`, `trial_id`, ...) needs the
# `viewer` role in that id's study to read and `experimenter` to change anything; a
# path with only ids no resolver knows needs the admin role (add a resolver in
# backend/study/access.py); a path without ids needs a login to read and admin to change.

ACCESS_KEY = "x-exostudy-access"
AccessRule = Literal["public", "participant", "login", "admin", "worker", "device",
                     "viewer", "experimenter", "owner"]
_READ = {"GET", "HEAD", "OPTIONS"}


def access(rule: AccessRule) -> dict[str, Any]:
    """What a route needs, for its decorator: `openapi_extra=access("owner")`."""
    return {ACCESS_KEY: rule}


def _path_params(route: BaseRoute) -> list[str]:
    return re.findall(r"\{(\w+)", getattr(route, "path", ""))


def rule_of(route: BaseRoute, method: str) -> AccessRule:
    """The rule a route's operation is checked against (declared, else the default)."""
    extra = getattr(route, "openapi_extra", None) or {}
    declared = extra.get(ACCESS_KEY)
    if declared is not None:
        return declared
    params = _path_params(route)
    if any(p in access_rules.RESOLVERS for p in params):
        return "viewer" if method in _READ else "experimenter"
    if any(p.endswith("_id") for p in params):
        # An id no resolver knows cannot be placed in a study: fail closed.
        return "admin"
    return "login" if method in _READ else "admin"


def _refuse(status: int, message: str) -> NoReturn:
    headers = {"WWW-Authenticate": "Bearer"} if status == 401 else None
    raise HTTPException(status, message, headers=headers)


def _credentials(conn: HTTPConnection) -> tuple[str | None, str | None]:
    scheme, _, value = conn.headers.get("authorization", "").partition(" ")
    bearer_token = value.strip() if scheme.lower() == "bearer" and value.strip() else None
    return bearer_token, conn.cookies.get(SESSION_COOKIE)


def _target(db: Session, conn: HTTPConnection, route: BaseRoute
            ) -> access_rules.Target | None:
    """The study the path's first known id belongs to; 404 if that id is unknown.
    A malformed id returns None: the route's own validation answers 422."""
    for name in _path_params(route):
        resolver = access_rules.RESOLVERS.get(name)
        if resolver is None:
            continue
        value = path_id(str(conn.path_params.get(name, "")))
        if value is None:
            return None
        found = resolver(db, value)
        if found is None:
            not_found(name.removesuffix("_id").replace("_", " "), value)
        return found
    return None


def _check(db: Session, conn: HTTPConnection, route: BaseRoute, rule: AccessRule,
           user: User) -> None:
    if rule == "login":
        return
    if rule == "admin":
        if user.role != "admin":
            _refuse(403, "this needs the admin role")
        return
    if rule == "worker":
        if user.role == "admin":
            return
        running = access_rules.running_study(db)
        if running is not None:
            g = access_rules.grant(db, user, running)
            if g is None or not access_rules.at_least(g.role, "experimenter"):
                _refuse(403, f"study {running} is using the device: only its experimenters "
                        "and owners (or an admin) may control the worker")
            return
        if not access_rules.at_least(access_rules.best_study_role(db, user), "experimenter"):
            _refuse(403, "controlling the worker needs the experimenter role in a study")
        return
    if rule == "device":
        _check_device(db, conn, route, user)
        return
    assert rule in access_rules.STUDY_ROLES, f"unknown access rule {rule!r}"
    target = _target(db, conn, route)
    if target is None or target.study_id is None:
        # No study in the path (or a malformed id, which the route refuses with 422,
        # or a row of no study, such as a virtual cohort's job): the caller must hold
        # the role somewhere.
        if not access_rules.at_least(access_rules.best_study_role(db, user), rule):
            _refuse(403, f"this needs the {rule} role in a study")
        return
    g = access_rules.grant(db, user, target.study_id)
    if g is None:
        _refuse(403, f"study {target.study_id}: you are not a member of this study")
    if not access_rules.at_least(g.role, rule):
        _refuse(403, f"study {target.study_id}: this needs the {rule} role; you are {g.role}")
    if not access_rules.site_allows(db, g, target.participant_id):
        _refuse(403, f"participant {target.participant_id}: belongs to another site than "
                f"yours ({g.site})")
    conn.state.grant = g


def _check_device(db: Session, conn: HTTPConnection, route: BaseRoute, user: User) -> None:
    """Rule `device` (pulse, controller, trial, bring-up): the lab's device grant, which
    only an administrator gives (`backend.study.device_grants`), and the experimenter
    role in the study the path names (a trial's), else in the study whose trial or
    recording is running, if any. Admins pass."""
    if user.role == "admin":
        return
    if not device_grants.holds(db, user):
        _refuse(403, device_grants.MISSING)
    target = _target(db, conn, route)
    study = target.study_id if target is not None else access_rules.running_study(db)
    if study is None:
        return
    g = access_rules.grant(db, user, study)
    if g is None or not access_rules.at_least(g.role, "experimenter"):
        _refuse(403, f"study {study}: using the device for it needs the experimenter role "
                "in it as well as the device grant")
    if target is not None:
        if not access_rules.site_allows(db, g, target.participant_id):
            _refuse(403, f"participant {target.participant_id}: belongs to another site "
                    f"than yours ({g.site})")
        conn.state.grant = g


def authorize(conn: HTTPConnection) -> None:
    """The single access check of every route (see the comment above `access`).

    401 without a valid login, 403 for a role or site that does not allow the
    operation, 404 for an unknown id in the path, 403 for a cookie-authenticated change
    from another origin or without the CSRF token; WebSockets from another origin are
    refused."""
    allowed = conn.app.state.settings.allowed_origins
    if conn.scope["type"] == "websocket":
        if web_surface.origin_verdict(conn, allowed) is False:
            raise WebSocketException(1008, "cross-site WebSocket refused")
        return
    route = conn.scope.get("route")
    if route is None or not getattr(route, "path", "").startswith("/api/"):
        return  # pages and assets: static shells whose data comes through the API
    method = conn.scope["method"]
    rule = rule_of(route, method)
    unsafe = method not in _READ
    if rule in ("public", "participant"):
        if unsafe and web_surface.origin_verdict(conn, allowed) is False:
            _refuse(403, "Origin: requests from another site are refused")
        return
    bearer_token, cookie_token = _credentials(conn)
    with conn.app.state.sessions() as db:
        found = resolve_token(db, bearer_token) if bearer_token else None
        via_cookie = False
        if found is None and cookie_token:
            found = resolve_token(db, cookie_token)
            via_cookie = found is not None
        if found is None:
            _refuse(401, "not logged in: POST /api/auth/login (cookie) or /api/auth/token "
                    "(bearer)")
        if via_cookie and unsafe and cookie_token:
            if web_surface.origin_verdict(conn, allowed) is not True:
                _refuse(403, "Origin: a change with the session cookie must come from this "
                        "site's pages (Origin or Referer header)")
            if not web_surface.csrf_ok(conn, cookie_token):
                _refuse(403, f"{web_surface.CSRF_HEADER}: missing or wrong CSRF token (the "
                        f"pages send the {web_surface.CSRF_COOKIE} cookie's value)")
        _check(db, conn, route, rule, found[0])
        conn.state.user_id = found[0].id


def document_access(app: FastAPI) -> None:
    """Make `app.openapi()` state each operation's rule (`x-exostudy-access`), its
    security schemes and its 401/403 answers, from the same `rule_of` the check uses."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        schema = build()
        schemes = schema.setdefault("components", {}).setdefault("securitySchemes", {})
        schemes.setdefault("HTTPBearer", {"type": "http", "scheme": "bearer"})
        schemes.setdefault("APIKeyCookie", {"type": "apiKey", "in": "cookie",
                                            "name": SESSION_COOKIE})
        # Routers are included lazily (FastAPI 0.16x): walk the flattened routes.
        for context in iter_route_contexts(app.routes):
            route = context.original_route
            if not isinstance(route, APIRoute) or not route.include_in_schema:
                continue
            item = schema.get("paths", {}).get(context.path_format or route.path_format, {})
            for method in route.methods or ():
                op = item.get(method.lower())
                if op is None:
                    continue
                rule = rule_of(route, method)
                op[ACCESS_KEY] = rule
                if "requestBody" in op:
                    op.setdefault("responses", {}).setdefault(
                        "413", {"description": "the body is larger than the server takes"})
                if rule in ("public", "participant"):
                    op.pop("security", None)
                    continue
                op.setdefault("security", [{"HTTPBearer": []}, {"APIKeyCookie": []}])
                responses = op.setdefault("responses", {})
                responses.setdefault("401", {"description": "not logged in"})
                responses.setdefault("403", {"description": f"needs: {rule} (role, site, "
                                             "or the CSRF check of a cookie login)"})
        app.openapi_schema = schema
        return schema

    app.openapi = openapi  # type: ignore[method-assign]
