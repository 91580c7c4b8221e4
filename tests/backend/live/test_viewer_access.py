"""The 3D view's own server (viser, on a loopback port) answers only the app's relay:
a request straight to its port, HTTP or WebSocket, without the app's secret gets 403,
while the relay behind the login still connects."""

from __future__ import annotations

import asyncio
import urllib.error
import urllib.request

import pytest
import viser
from fastapi.testclient import TestClient
from websockets.asyncio.client import connect
from websockets.exceptions import InvalidStatus


def test_viser_port_refuses_anyone_but_the_relay(client: TestClient) -> None:
    assert client.get("/viewer/").status_code == 200  # starts viser behind the login
    port = client.get("/viewer/status").json()["port"]
    assert port
    with pytest.raises(urllib.error.HTTPError) as http:
        urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10)
    assert http.value.code == 403

    async def direct() -> None:
        async with connect(f"ws://127.0.0.1:{port}",
                           subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
                           open_timeout=10):
            pass

    with pytest.raises(InvalidStatus) as ws:
        asyncio.run(direct())
    assert ws.value.response.status_code == 403
    # Through the app, with its login, the same socket opens.
    with client.websocket_connect("/viewer", subprotocols=[f"viser-v{viser.__version__}"]
                                  ) as relayed:
        assert relayed.receive_bytes()
    anonymous = TestClient(client.app)
    assert anonymous.get("/viewer/status").status_code == 401
