"""The live WebSocket: ticks as they arrive (at most `stream_rate` messages per second),
plus status messages. It ends with its login (`backend.api.socket_logins`)."""

from __future__ import annotations

import asyncio
import contextlib
import logging

from fastapi import APIRouter, WebSocket, WebSocketDisconnect, status

from backend.api.deps import (
    SESSION_COOKIE,
    RuntimeDep,
    SessionFactoryDep,
    SocketLoginsDep,
    login_from_token,
)

router = APIRouter(tags=["live"])
log = logging.getLogger(__name__)


class _UnsupportedFrameError(Exception):
    """The browser sent something the console protocol does not have."""


@router.websocket("/ws/live")
async def live(websocket: WebSocket, sessions: SessionFactoryDep, runtime: RuntimeDep,
               logins: SocketLoginsDep) -> None:
    """Stream `LiveTicks` and `LiveStatus` messages (see `backend.schemas.live`)."""
    # Browsers cannot set headers on a WebSocket, so the session cookie is the login;
    # closing before accepting refuses the handshake (HTTP 403).
    login = await asyncio.to_thread(login_from_token, sessions,
                                    websocket.cookies.get(SESSION_COOKIE))
    if login is None:
        await websocket.close(code=status.WS_1008_POLICY_VIOLATION, reason="not logged in")
        return
    user, token = login
    await websocket.accept()

    async def _drain_incoming() -> None:
        # The console sends nothing we need; reading notices a closed socket. A binary
        # frame is not part of the protocol: one log line and close 1003.
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            if message.get("bytes") is not None:
                raise _UnsupportedFrameError("binary frame")

    async def _send_queued() -> None:
        while True:
            await websocket.send_text(await client.queue.get())

    # The client is registered only inside the try, so every way out (a closed socket,
    # a failed send, a bad frame, the login ending, cancellation) unregisters it.
    client = runtime.stream.connect()
    tasks: list[asyncio.Task[object]] = []
    try:
        client.offer('{"type":"status","health":' + runtime.health().model_dump_json() + "}")
        # Long-lived tasks per connection (not one per message): whichever ends first
        # ends the connection.
        tasks = [asyncio.create_task(_drain_incoming()), asyncio.create_task(_send_queued()),
                 asyncio.create_task(logins.watch(websocket, sessions, user.id, token.id))]
        done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        for task in done:
            if not task.cancelled() and isinstance(task.exception(), _UnsupportedFrameError):
                log.warning("/ws/live: user %d sent a binary frame; closing with 1003",
                            user.id)
                with contextlib.suppress(RuntimeError, WebSocketDisconnect):
                    await websocket.close(code=status.WS_1003_UNSUPPORTED_DATA,
                                          reason="binary frames are not supported")
    finally:
        runtime.stream.disconnect(client)
        for task in tasks:
            task.cancel()
        for task in tasks:
            # Each one awaited, whatever the others raised: none is left pending.
            with contextlib.suppress(BaseException):
                await task
