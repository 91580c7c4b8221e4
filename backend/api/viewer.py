"""The 3D view: a viser scene of the wearer's pelvis and thighs and the exoskeleton's
links, coloured by lock state, moved by the live ticks.

viser runs its own server (thread and event loop) bound to 127.0.0.1 on a free port.
The only way in is through this app: `/viewer/` serves viser's self-contained client
page behind the login, and the WebSocket `/viewer` (where the client connects, derived
from the page's URL) is relayed to viser byte for byte, keeping its subprotocol. The
server and the tick consumer start on the first visit and stop with the process.

viser's own port answers nobody but the relay: every request to it (HTTP or WebSocket
handshake) must carry a random secret that only this process knows (`_SECRET`, sent by
the relay as a header), or it gets 403. Any other local user or process that finds the
port therefore sees nothing, without the app's login.
"""

from __future__ import annotations

import asyncio
import atexit
import contextlib
import json
import logging
import math
import secrets
import socket
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Request, WebSocket, WebSocketDisconnect, status
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from pydantic import BaseModel

from backend.api.deps import SESSION_COOKIE, login_from_token

log = logging.getLogger(__name__)
router = APIRouter(include_in_schema=False)

# Body sizes (m): a schematic adult, enough to read posture and lock state.
HIP_HEIGHT = 0.95
HIP_HALF_WIDTH = 0.10
THIGH_LENGTH = 0.43
EXO_OFFSET = 0.07  # exoskeleton link, lateral of the thigh
FREE = (150, 156, 166)
LOCKED = {"left": (31, 111, 235), "right": (217, 72, 15)}
ENGAGED_ONLY = (240, 165, 0)  # ratchet engaged without a lock command (held or releasing)


class ViewerStatus(BaseModel):
    """What the viewer is doing (for the page and the tests)."""

    running: bool
    port: int | None
    updates: int
    clients: int
    last_q_deg: tuple[float, float] | None


@dataclass
class _Viewer:
    server: Any
    port: int
    handles: dict[str, Any]
    updates: int = 0
    clients: int = 0
    last_q: tuple[float, float] | None = None
    task: asyncio.Task[None] | None = field(default=None, repr=False)


#: The header and the per-process secret the relay sends to viser's port.
SECRET_HEADER = "X-ExoStudy-Viewer-Secret"
_SECRET = secrets.token_urlsafe(32)


class _Guarded:
    """Stands in for the `websockets` package inside viser's server module only, so
    that viser's `websockets.asyncio.server.serve(...)` gets a `process_request` that
    refuses (403) any request without the secret before viser's own handler runs."""

    def __init__(self, real: Any, path: tuple[str, ...] = ()) -> None:
        self._real, self._path = real, path

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._real, name)
        if (*self._path, name) in (("asyncio",), ("asyncio", "server")):
            return _Guarded(attr, (*self._path, name))
        if self._path == ("asyncio", "server") and name == "serve":
            return _guarded_serve(attr)
        return attr


def _guarded_serve(serve: Any) -> Any:
    def wrapper(*args: Any, process_request: Any = None, **kwargs: Any) -> Any:
        def check(connection: Any, request: Any) -> Any:
            sent = request.headers.get(SECRET_HEADER, "")
            if not secrets.compare_digest(sent.encode(), _SECRET.encode()):
                return connection.respond(403, "the 3D view is reached through ExoStudy\n")
            return process_request(connection, request) if process_request else None

        return serve(*args, process_request=check, **kwargs)

    return wrapper


def _guard_viser() -> None:
    from viser.infra import _infra

    if not isinstance(_infra.websockets, _Guarded):
        _infra.websockets = _Guarded(_infra.websockets)  # type: ignore[assignment]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _about_y(angle: float) -> tuple[float, float, float, float]:
    """Quaternion (wxyz) of a rotation by `angle` about the lateral (y) axis."""
    return (math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0)


def _build_scene(server: Any) -> dict[str, Any]:
    scene = server.scene
    scene.set_up_direction("+z")
    scene.add_grid("/floor", width=3.0, height=3.0, position=(0.0, 0.0, 0.0))
    scene.add_box("/pelvis", color=(120, 126, 138),
                  dimensions=(0.16, 2 * HIP_HALF_WIDTH + 0.12, 0.14),
                  position=(0.0, 0.0, HIP_HEIGHT + 0.03))
    scene.add_box("/trunk", color=(190, 196, 204), dimensions=(0.14, 0.30, 0.50),
                  position=(0.0, 0.0, HIP_HEIGHT + 0.35), opacity=0.6)
    handles: dict[str, Any] = {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        y = sign * HIP_HALF_WIDTH
        hip = scene.add_frame(f"/hip_{side}", show_axes=False, position=(0.0, y, HIP_HEIGHT))
        scene.add_box(f"/hip_{side}/thigh", color=(226, 196, 170),
                      dimensions=(0.13, 0.13, THIGH_LENGTH), position=(0.0, 0.0, -THIGH_LENGTH / 2))
        scene.add_box(f"/hip_{side}/knee", color=(200, 170, 150), dimensions=(0.12, 0.12, 0.05),
                      position=(0.0, 0.0, -THIGH_LENGTH))
        # The exoskeleton: a hip actuator fixed to the pelvis and a link along the thigh.
        actuator = scene.add_box(f"/actuator_{side}", color=FREE, dimensions=(0.10, 0.04, 0.10),
                                 position=(0.0, y + sign * EXO_OFFSET, HIP_HEIGHT))
        link = scene.add_box(f"/hip_{side}/exo_link", color=FREE, dimensions=(0.04, 0.025, 0.32),
                             position=(0.0, sign * EXO_OFFSET, -0.18))
        handles[f"hip_{side}"] = hip
        handles[f"link_{side}"] = link
        handles[f"actuator_{side}"] = actuator
    scene.add_label("/label_left", "left", position=(0.0, 0.35, HIP_HEIGHT + 0.1))
    scene.add_label("/label_right", "right", position=(0.0, -0.35, HIP_HEIGHT + 0.1))
    return handles


def _start() -> _Viewer:
    import viser

    _guard_viser()
    # viser moves to the next port if the one asked for is taken: always read it back.
    server = viser.ViserServer(host="127.0.0.1", port=_free_port(), verbose=False)
    # The share button talks to an outside server; studies run offline.
    server.gui.configure_theme(show_share_button=False, show_logo=False)
    handles = _build_scene(server)
    server.initial_camera.position = (1.3, 1.0, 1.25)
    server.initial_camera.look_at = (0.0, 0.0, 0.8)
    atexit.register(server.stop)
    return _Viewer(server=server, port=int(server.get_port()), handles=handles)


def _apply(viewer: _Viewer, tick: dict[str, Any]) -> None:
    with viewer.server.atomic():
        for side in ("left", "right"):
            q = tick.get(f"q_{side}")
            if q is not None:
                viewer.handles[f"hip_{side}"].wxyz = _about_y(-float(q))
            held = bool(tick.get(f"lock_{side}"))
            engaged = bool(tick.get(f"locked_{side}"))
            colour = LOCKED[side] if held else ENGAGED_ONLY if engaged else FREE
            viewer.handles[f"link_{side}"].color = colour
            viewer.handles[f"actuator_{side}"].color = colour
    if tick.get("q_left") is not None and tick.get("q_right") is not None:
        viewer.last_q = (math.degrees(tick["q_left"]), math.degrees(tick["q_right"]))
    viewer.updates += 1


async def _follow_ticks(app: Any, viewer: _Viewer) -> None:
    """Pose the scene from the live stream (the same messages the consoles get)."""
    stream = app.state.runtime.stream
    client = stream.connect(console=False)
    try:
        while True:
            msg = json.loads(await client.queue.get())
            if msg.get("type") != "ticks":
                continue
            cols = msg["columns"]
            n = len(cols["t"])
            if n:
                _apply(viewer, {k: v[n - 1] for k, v in cols.items()})
    finally:
        stream.disconnect(client)
        # The app's event loop is closing (the task is cancelled with it): viser goes too.
        app.state.viewer = None
        viewer.server.stop()


_starting = threading.Lock()


def _start_once(app: Any) -> _Viewer:
    with _starting:
        viewer: _Viewer | None = getattr(app.state, "viewer", None)
        if viewer is None:
            viewer = _start()
            app.state.viewer = viewer
        return viewer


async def _viewer(app: Any) -> _Viewer:
    viewer = await asyncio.to_thread(_start_once, app)
    if viewer.task is None or viewer.task.done():
        viewer.task = asyncio.get_running_loop().create_task(_follow_ticks(app, viewer))
    return viewer


def _logged_in(app: Any, cookies: dict[str, str]) -> bool:
    return login_from_token(app.state.sessions, cookies.get(SESSION_COOKIE)) is not None


def _client_html() -> str:
    import viser

    return (Path(viser.__file__).parent / "client" / "build" / "index.html").read_text()


@router.get("/viewer")
def viewer_redirect() -> RedirectResponse:
    """The client derives its socket from the page URL: serve it at `/viewer/`."""
    return RedirectResponse("/viewer/", status_code=307)


@router.get("/viewer/")
async def viewer_page(request: Request) -> Response:
    """viser's client page (one self-contained file from the wheel)."""
    if not await asyncio.to_thread(_logged_in, request.app, dict(request.cookies)):
        return RedirectResponse("/login?next=/viewer/", status_code=303)
    await _viewer(request.app)
    return HTMLResponse(_client_html())


@router.get("/viewer/status", response_model=ViewerStatus)
async def viewer_status(request: Request) -> Response:
    """Is the 3D view running and following the ticks?"""
    if not await asyncio.to_thread(_logged_in, request.app, dict(request.cookies)):
        return Response(status_code=401)
    v: _Viewer | None = getattr(request.app.state, "viewer", None)
    body = ViewerStatus(running=v is not None, port=v.port if v else None,
                        updates=v.updates if v else 0, clients=v.clients if v else 0,
                        last_q_deg=v.last_q if v else None)
    return Response(body.model_dump_json(), media_type="application/json")


@router.websocket("/viewer")
async def viewer_socket(websocket: WebSocket) -> None:
    """Relay the client's WebSocket to viser, both ways, unchanged."""
    from websockets.asyncio.client import connect
    from websockets.typing import Subprotocol

    login = await asyncio.to_thread(login_from_token, websocket.app.state.sessions,
                                    websocket.cookies.get(SESSION_COOKIE))
    if login is None:
        await websocket.close(code=status.WS_1008_POLICY_VIOLATION, reason="not logged in")
        return
    viewer = await _viewer(websocket.app)
    asked = [p for p in websocket.scope.get("subprotocols", []) if p.startswith("viser-v")]
    upstream_cm = connect(f"ws://127.0.0.1:{viewer.port}",
                          subprotocols=[Subprotocol(p) for p in asked] or None,
                          additional_headers={SECRET_HEADER: _SECRET},
                          compression=None, max_size=None, open_timeout=5)
    try:
        upstream = await upstream_cm.__aenter__()
    except OSError:
        await websocket.close(code=status.WS_1011_INTERNAL_ERROR, reason="viewer not running")
        return
    await websocket.accept(subprotocol=upstream.subprotocol)
    viewer.clients += 1

    async def down() -> None:
        async for message in upstream:
            if isinstance(message, bytes):
                await websocket.send_bytes(message)
            else:
                await websocket.send_text(message)

    async def up() -> None:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            if message.get("bytes") is not None:
                await upstream.send(message["bytes"])
            elif message.get("text") is not None:
                await upstream.send(message["text"])

    # The relay ends with its login, like the live socket.
    watch = websocket.app.state.socket_logins.watch(websocket, websocket.app.state.sessions,
                                                    login[0].id, login[1].id)
    tasks = [asyncio.create_task(down()), asyncio.create_task(up()),
             asyncio.create_task(watch)]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        viewer.clients -= 1
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(BaseException):
                await t
        await upstream_cm.__aexit__(None, None, None)
        with contextlib.suppress(RuntimeError):
            await websocket.close()
