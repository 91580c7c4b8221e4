"""The staged start (`backend.core.starting`): "starting" answers while the application
loads, the application itself once its start-up completed, an exit when it fails, and
its shutdown run when the server stops."""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import Callable

from backend.core.starting import Message, Receive, Scope, Send, StagedApp

DEADLINE_S = 30.0


class FakeApp:
    """An ASGI app that records its lifespan and answers 200 "real"."""

    def __init__(self, fail_startup: str = "") -> None:
        self.fail_startup = fail_startup
        self.events: list[str] = []

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "lifespan":
            while True:
                message = await receive()
                self.events.append(message["type"])
                if message["type"] == "lifespan.startup":
                    if self.fail_startup:
                        await send({"type": "lifespan.startup.failed",
                                    "message": self.fail_startup})
                        return
                    await send({"type": "lifespan.startup.complete"})
                else:
                    await send({"type": "lifespan.shutdown.complete"})
                    return
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b"real"})


async def _get(app: StagedApp, path: str) -> tuple[int, dict[bytes, bytes], bytes]:
    sent: list[Message] = []  # what the app sent

    async def receive() -> Message:
        return {"type": "http.request", "body": b""}

    async def send(message: Message) -> None:
        sent.append(message)

    await app({"type": "http", "path": path, "method": "GET", "headers": []}, receive, send)
    return sent[0]["status"], dict(sent[0]["headers"]), sent[1]["body"]


class Server:
    """Drives the staged app's lifespan as uvicorn does."""

    def __init__(self, app: StagedApp) -> None:
        self.app = app
        self.inbox: asyncio.Queue[Message] = asyncio.Queue()
        self.outbox: asyncio.Queue[Message] = asyncio.Queue()
        self.task: asyncio.Task[None] | None = None

    async def start(self) -> Message:
        self.task = asyncio.create_task(self.app({"type": "lifespan", "state": {}},
                                                 self.inbox.get, self.outbox.put))
        await self.inbox.put({"type": "lifespan.startup"})
        return await asyncio.wait_for(self.outbox.get(), DEADLINE_S)

    async def stop(self) -> Message:
        await self.inbox.put({"type": "lifespan.shutdown"})
        return await asyncio.wait_for(self.outbox.get(), DEADLINE_S)


async def _until(cond: Callable[[], bool]) -> None:
    """Wait on progress, with a deadline."""
    loop = asyncio.get_running_loop()
    end = loop.time() + DEADLINE_S
    while not cond():
        assert loop.time() < end, "timed out"
        await asyncio.sleep(0.01)


def test_answers_starting_then_hands_over_then_stops_the_application() -> None:
    inner = FakeApp()
    release = threading.Event()
    failures: list[str] = []

    def load() -> FakeApp:
        assert release.wait(DEADLINE_S)
        return inner

    async def scenario() -> None:
        staged = StagedApp(load, failures.append)
        server = Server(staged)
        assert (await server.start())["type"] == "lifespan.startup.complete"  # listens now
        status, headers, body = await _get(staged, "/api/health")
        assert status == 503 and headers[b"retry-after"] == b"1"
        doc = json.loads(body)
        assert doc["status"] == "starting" and doc["worker"]["alive"] is False
        assert "loading the application" in doc["detail"]
        status, headers, body = await _get(staged, "/live")
        assert status == 503 and b"starting" in body
        assert headers[b"content-type"].startswith(b"text/html")
        assert (await _get(staged, "/api/studies"))[0] == 503  # no API before the app
        release.set()
        await _until(lambda: staged.ready)
        assert inner.events == ["lifespan.startup"]
        assert await _get(staged, "/api/health") == (200, {}, b"real")
        assert (await server.stop())["type"] == "lifespan.shutdown.complete"
        assert inner.events == ["lifespan.startup", "lifespan.shutdown"]

    asyncio.run(scenario())
    assert failures == []


def test_a_failed_start_up_is_reported_and_the_app_never_serves() -> None:
    inner = FakeApp(fail_startup="refusing to listen on 0.0.0.0")
    failures: list[str] = []

    async def scenario() -> None:
        staged = StagedApp(lambda: inner, failures.append)
        server = Server(staged)
        await server.start()
        await _until(lambda: bool(failures))
        assert not staged.ready
        status, _, body = await _get(staged, "/api/health")
        assert status == 503 and json.loads(body)["phase"] == "failed"
        assert (await server.stop())["type"] == "lifespan.shutdown.complete"
        assert inner.events == ["lifespan.startup"]  # no shutdown of what never started

    asyncio.run(scenario())
    assert failures == ["refusing to listen on 0.0.0.0"]


def test_a_failed_import_is_reported() -> None:
    failures: list[str] = []

    def load() -> FakeApp:
        raise ImportError("no module named 'numba'")

    async def scenario() -> None:
        staged = StagedApp(load, failures.append)
        server = Server(staged)
        await server.start()
        await _until(lambda: bool(failures))
        await server.stop()

    asyncio.run(scenario())
    assert len(failures) == 1 and "no module named 'numba'" in failures[0]
