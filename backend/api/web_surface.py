"""What the browser-facing surface adds to every response and checks on every request:
security headers, a body-size limit before any parsing, the same-origin check and the
CSRF token of cookie-authenticated requests.

Cross-site request forgery: a browser attaches the session cookie to requests other
sites make, so a cookie-authenticated request that changes something must (1) come
from our own origin (`Origin`, else `Referer`, names this host) and (2) carry the
`X-CSRF-Token` header, which another site can neither read nor set without a CORS
preflight we never grant. The token is derived from the session token, so it changes
with every login and needs no storage. Bearer-token requests are exempt: browsers never
attach those by themselves.
"""

from __future__ import annotations

import hashlib
import hmac
import re
from collections.abc import Iterable, Sequence
from typing import Any
from urllib.parse import urlsplit

from fastapi import params
from fastapi.routing import APIRoute
from starlette.datastructures import Headers
from starlette.exceptions import HTTPException
from starlette.requests import HTTPConnection
from starlette.types import ASGIApp, Message, Receive, Scope, Send

#: Cookie the pages' script reads to send the CSRF header (not httponly on purpose).
CSRF_COOKIE = "exostudy_csrf"
CSRF_HEADER = "x-csrf-token"

#: Content-Security-Policy of every page. Scripts and styles come from this origin only
# (uPlot is served from /vendor, Swagger UI from /docs-assets); inline styles are allowed
# because uPlot and viser's client set style attributes; viser's client needs blob:
# workers and WebAssembly; nothing may frame the app (clickjacking).
CSP = ("default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; "
       "style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; "
       "font-src 'self' data:; connect-src 'self'; worker-src 'self' blob:; "
       "object-src 'none'; base-uri 'self'; form-action 'self'; frame-ancestors 'none'")
#: The viser client bundles its code in the one HTML file, as inline scripts.
VIEWER_CSP = CSP.replace("script-src 'self'", "script-src 'self' 'unsafe-inline'")

SECURITY_HEADERS: tuple[tuple[bytes, bytes], ...] = (
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"same-origin"),
    (b"cross-origin-opener-policy", b"same-origin"),
    (b"permissions-policy", b"camera=(), microphone=(), geolocation=()"),
)


def csrf_token_for(session_token: str) -> str:
    """The CSRF token that goes with a session token."""
    return hmac.new(session_token.encode("utf-8"), b"exostudy-csrf",
                    hashlib.sha256).hexdigest()


def csrf_ok(conn: HTTPConnection, session_token: str) -> bool:
    """True if the request carries the CSRF token of its session."""
    sent = conn.headers.get(CSRF_HEADER, "")
    return hmac.compare_digest(sent.encode("utf-8", "replace"),
                               csrf_token_for(session_token).encode("ascii"))


def _netloc(url: str) -> str | None:
    try:
        parts = urlsplit(url)
    except ValueError:
        return None
    return parts.netloc.lower() if parts.scheme in ("http", "https") and parts.netloc else None


def origin_verdict(conn: HTTPConnection, allowed: Iterable[str] = ()) -> bool | None:
    """True: the request comes from this host (or an allowed origin); False: from
    another site; None: the browser sent neither `Origin` nor `Referer`."""
    host = conn.headers.get("host", "").lower()
    extra = {n for n in (_netloc(a) for a in allowed) if n}
    claimed = conn.headers.get("origin")
    if claimed is None:
        referer = conn.headers.get("referer")
        if referer is None:
            return None
        claimed = referer
    netloc = _netloc(claimed)
    return netloc is not None and (netloc == host or netloc in extra)


class SecurityHeaders:
    """Adds CSP, frame, nosniff and referrer headers to every HTTP response."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path: str = scope.get("path", "")
        csp = (VIEWER_CSP if path.startswith("/viewer") else CSP).encode("ascii")

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                present = {k.lower() for k, _ in message.get("headers", [])}
                headers = list(message.get("headers", []))
                for k, v in ((b"content-security-policy", csp), *SECURITY_HEADERS):
                    if k not in present:
                        headers.append((k, v))
                message["headers"] = headers
            await send(message)

        await self.app(scope, receive, send_with_headers)


class BodyLimit:
    """Refuses a request body larger than its route's limit with 413, before anything
    reads it: at once when `Content-Length` says so, else as soon as the streamed body
    passes the limit (nothing larger is ever held in memory).

    One setting per kind of body: routes that take a file (a `File()` parameter: the
    utility-set import, XDF attachments) allow `upload_limit` (`max_upload_bytes`),
    every other route `limit` (`max_body_bytes`, JSON bodies). `upload_paths` holds the
    file routes' path templates; the app fills it once its routes are included.
    """

    def __init__(self, app: ASGIApp, limit: int, upload_limit: int | None = None,
                 upload_paths: list[str] | None = None) -> None:
        self.app = app
        self.limit = limit
        self.upload_limit = upload_limit if upload_limit is not None else limit
        self.upload_paths = upload_paths if upload_paths is not None else []
        self._patterns: list[re.Pattern[str]] | None = None

    def _limit_for(self, path: str) -> int:
        if self._patterns is None or len(self._patterns) != len(self.upload_paths):
            self._patterns = [re.compile("^" + re.sub(r"\\{[^}]+\\}", "[^/]+", re.escape(p))
                                         + "$") for p in self.upload_paths]
        if any(p.match(path) for p in self._patterns):
            return self.upload_limit
        return self.limit

    async def _refuse(self, send: Send, limit: int) -> None:
        body = (f'{{"detail":[{{"loc":["body"],"msg":"the body is larger than {limit} '
                f'bytes","type":"too_large"}}]}}').encode()
        await send({"type": "http.response.start", "status": 413,
                    "headers": [(b"content-type", b"application/json"),
                                (b"content-length", str(len(body)).encode()),
                                (b"connection", b"close")]})
        await send({"type": "http.response.body", "body": body})

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self._limit_for(scope.get("path", ""))
        declared = Headers(scope=scope).get("content-length")
        if declared is not None and (not declared.isascii() or not declared.isdigit()
                                     or len(declared) > 20 or int(declared) > limit):
            await self._refuse(send, limit)
            return
        seen = 0
        started = False

        async def counted_receive() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    raise _TooLarge(413, [{"loc": ["body"], "type": "too_large",
                                           "msg": f"the body is larger than {limit} bytes"}])
            return message

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, counted_receive, tracking_send)
        except _TooLarge:
            if not started:
                await self._refuse(send, limit)


def file_routes(routes: Sequence[APIRoute]) -> list[str]:
    """Path templates of the routes that take a file (a `File()` parameter)."""
    return [route.path_format for route in routes
            if any(isinstance(p.field_info, params.File) for p in route.dependant.body_params)]


class _TooLarge(HTTPException):
    """Raised inside the app when a streamed body passes the limit; an HTTPException,
    so the framework answers 413 even from inside its body parsing."""

    def __init__(self, status_code: int, detail: Any) -> None:
        super().__init__(status_code)
        self.detail = detail
