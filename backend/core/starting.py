"""Listen first, load second: the ASGI app `exostudy serve` runs while the real one loads.

Importing the application (numpy, scipy, numba, matplotlib, SQLAlchemy, FastAPI and the
project's packages) costs seconds of CPU, and the lifespan then migrates the database,
loads the default sets, spawns the device simulator and the worker. On a loaded laptop
that took over 20 s, during which the port refused connections and a browser showed an
error. `StagedApp` is what uvicorn serves from the first moment: it answers at once,
loads the real app in a thread, runs the real app's start-up, and from then on hands
every request to it.

While loading, every request gets a 503 with `Retry-After` (pages a short page that
reloads itself, `/api/health` a JSON body saying the server is starting): nothing can be
read, written or run before the real app is there, so no controller can start before
the worker's safety checks are in place. Clients that wait for a 200 from `/api/health`
(the tests, scripts) wait for the real app, as before. If the real app fails to load or
to start (for example it refuses a non-local address while an account has the published
demo password), the server exits with the error, as it did before it listened early.

Imports only the standard library, so it is listening within a second.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any

log = logging.getLogger(__name__)

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

#: Seconds a client is asked to wait before asking again.
RETRY_AFTER_S = 1

_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta http-equiv="refresh" content="1">
<title>ExoStudy is starting</title></head>
<body><p>ExoStudy is starting; this page reloads itself.</p></body></html>
"""


class StagedApp:
    """Answers "starting" until `load()` (run in a thread) has returned the real app and
    its lifespan start-up has completed; then is the real app. `on_failure(message)` is
    called if either fails (the caller stops the server)."""

    def __init__(self, load: Callable[[], ASGIApp],
                 on_failure: Callable[[str], None]) -> None:
        self._load = load
        self._on_failure = on_failure
        self._app: ASGIApp | None = None
        self._started_at = time.monotonic()
        self._phase = "loading the application"
        self._failed = ""
        self._to_app: asyncio.Queue[Message] = asyncio.Queue()
        self._from_app: asyncio.Queue[Message] = asyncio.Queue()
        self._app_lifespan: asyncio.Task[None] | None = None

    @property
    def ready(self) -> bool:
        """Whether requests now go to the real app."""
        return self._app is not None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "lifespan":
            await self._lifespan(scope, receive, send)
            return
        app = self._app
        if app is not None:
            await app(scope, receive, send)
        elif scope["type"] == "websocket":
            await receive()  # websocket.connect
            await send({"type": "websocket.close", "code": 1013,
                        "reason": "ExoStudy is starting"})
        elif scope["type"] == "http":
            await self._starting(scope, send)

    async def _starting(self, scope: Scope, send: Send) -> None:
        path = str(scope.get("path", ""))
        waited = round(time.monotonic() - self._started_at, 1)
        if path.startswith("/api/"):
            body = json.dumps({
                "detail": f"ExoStudy is starting ({self._phase}, {waited} s so far); ask "
                f"again in {RETRY_AFTER_S} s",
                "status": "starting", "phase": self._phase,
                "worker": {"alive": False, "status": "starting"},
            }).encode()
            kind = b"application/json"
        else:
            body, kind = _PAGE.encode(), b"text/html; charset=utf-8"
        await send({"type": "http.response.start", "status": 503, "headers": [
            (b"content-type", kind), (b"content-length", str(len(body)).encode()),
            (b"retry-after", str(RETRY_AFTER_S).encode()), (b"cache-control", b"no-store"),
        ]})
        await send({"type": "http.response.body", "body": body})

    async def _lifespan(self, scope: Scope, receive: Receive, send: Send) -> None:
        await receive()  # lifespan.startup
        await send({"type": "lifespan.startup.complete"})  # uvicorn now listens
        loading = asyncio.create_task(self._start(scope), name="load-application")
        await receive()  # lifespan.shutdown, when the server stops
        # A start in progress finishes first, so a worker it spawned is stopped below.
        await asyncio.wait({loading})
        if self._app is not None and self._app_lifespan is not None:
            await self._to_app.put({"type": "lifespan.shutdown"})
            message = await self._from_app.get()
            if message["type"] == "lifespan.shutdown.failed":
                log.error("stopping the application failed: %s", message.get("message", ""))
            await asyncio.wait({self._app_lifespan})
        await send({"type": "lifespan.shutdown.complete"})

    async def _start(self, scope: Scope) -> None:
        try:
            app = await asyncio.to_thread(self._load)
        except Exception as exc:  # the import or the app factory failed
            log.exception("loading the application failed")
            self._fail(f"loading the application failed: {exc}")
            return
        self._phase = "starting the application (database, default sets, worker)"
        inner = dict(scope)
        inner["state"] = scope.get("state", {})
        self._app_lifespan = asyncio.create_task(
            self._run_lifespan(app, inner), name="application-lifespan")
        await self._to_app.put({"type": "lifespan.startup"})
        message = await self._from_app.get()
        if message["type"] != "lifespan.startup.complete":
            self._app_lifespan = None
            self._fail(str(message.get("message", "the application's start-up failed")))
            return
        self._app = app
        log.info("ExoStudy ready after %.1f s", time.monotonic() - self._started_at)

    async def _run_lifespan(self, app: ASGIApp, scope: Scope) -> None:
        try:
            await app(scope, self._to_app.get, self._from_app.put)
        except Exception as exc:  # the app raised instead of reporting failure
            await self._from_app.put({"type": "lifespan.startup.failed", "message": str(exc)})

    def _fail(self, message: str) -> None:
        self._failed = message
        self._phase = "failed"
        self._on_failure(message)
