"""The live WebSocket: ticks at about 30 messages per second, plus status messages."""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, WebSocket, WebSocketDisconnect, status

from backend.api.deps import SESSION_COOKIE, login_from_token
from backend.runtime import Runtime

router = APIRouter(tags=["live"])


@router.websocket("/ws/live")
async def live(websocket: WebSocket) -> None:
    """Stream `LiveTicks` and `LiveStatus` messages (see `backend.schemas.live`)."""
    # Browsers cannot set headers on a WebSocket, so the session cookie is the login;
    # closing before accepting refuses the handshake (HTTP 403).
    login = await asyncio.to_thread(login_from_token, websocket.app.state.sessions,
                                    websocket.cookies.get(SESSION_COOKIE))
    if login is None:
        await websocket.close(code=status.WS_1008_POLICY_VIOLATION, reason="not logged in")
        return
    runtime: Runtime = websocket.app.state.runtime
    await websocket.accept()
    client = runtime.stream.connect()
    client.offer(
        '{"type":"status","health":' + runtime.health().model_dump_json() + "}"
    )

    async def _drain_incoming() -> None:
        # The console sends nothing we need; reading notices a closed socket.
        while True:
            await websocket.receive_text()

    reader = asyncio.create_task(_drain_incoming())
    try:
        while True:
            get = asyncio.create_task(client.queue.get())
            done, _ = await asyncio.wait({get, reader}, return_when=asyncio.FIRST_COMPLETED)
            if reader in done:
                get.cancel()
                break
            await websocket.send_text(get.result())
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        runtime.stream.disconnect(client)
        reader.cancel()
        with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, RuntimeError):
            await reader
