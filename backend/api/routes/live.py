"""The live WebSocket: ticks as they arrive (at most `stream_rate` messages per second),
plus status messages."""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, WebSocket, WebSocketDisconnect, status

from backend.api.deps import (
    SESSION_COOKIE,
    RuntimeDep,
    SessionFactoryDep,
    login_from_token,
)

router = APIRouter(tags=["live"])


@router.websocket("/ws/live")
async def live(websocket: WebSocket, sessions: SessionFactoryDep,
               runtime: RuntimeDep) -> None:
    """Stream `LiveTicks` and `LiveStatus` messages (see `backend.schemas.live`)."""
    # Browsers cannot set headers on a WebSocket, so the session cookie is the login;
    # closing before accepting refuses the handshake (HTTP 403).
    login = await asyncio.to_thread(login_from_token, sessions,
                                    websocket.cookies.get(SESSION_COOKIE))
    if login is None:
        await websocket.close(code=status.WS_1008_POLICY_VIOLATION, reason="not logged in")
        return
    await websocket.accept()
    client = runtime.stream.connect()
    client.offer(
        '{"type":"status","health":' + runtime.health().model_dump_json() + "}"
    )

    async def _drain_incoming() -> None:
        # The console sends nothing we need; reading notices a closed socket.
        while True:
            await websocket.receive_text()

    async def _send_queued() -> None:
        while True:
            await websocket.send_text(await client.queue.get())

    # Two long-lived tasks per connection (not one per message): whichever ends first,
    # a closed socket or a failed send, ends the connection.
    reader = asyncio.create_task(_drain_incoming())
    sender = asyncio.create_task(_send_queued())
    try:
        await asyncio.wait({reader, sender}, return_when=asyncio.FIRST_COMPLETED)
    finally:
        runtime.stream.disconnect(client)
        for task in (reader, sender):
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, RuntimeError):
                await task
