"""The app on a loopback port in this process, and a plain HTTP client for it.

Used by commands that drive the server the way a user's script would (the virtual
study): a real uvicorn server and real HTTP requests, with only the standard library
on the client side, so they run on an install without the development extras.
"""

from __future__ import annotations

import http.client
import json
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlencode

import uvicorn
from fastapi import FastAPI


@dataclass(frozen=True)
class Response:
    """What a request returned."""

    method: str
    path: str
    status_code: int
    content: bytes

    @property
    def text(self) -> str:
        """The body as UTF-8 text."""
        return self.content.decode("utf-8", errors="replace")

    def json(self) -> Any:
        """The body parsed as JSON."""
        return json.loads(self.content)


class ApiClient:
    """Keep-alive HTTP/1.1 to one server, with an optional bearer token.

    One connection, one request at a time (the caller is a sequential script); a
    connection the server closed is reopened once.
    """

    def __init__(self, host: str, port: int, timeout_s: float = 600.0) -> None:
        self.host, self.port, self.timeout_s = host, port, timeout_s
        self.token: str | None = None
        self._conn: http.client.HTTPConnection | None = None

    def _connection(self) -> http.client.HTTPConnection:
        if self._conn is None:
            self._conn = http.client.HTTPConnection(self.host, self.port,
                                                    timeout=self.timeout_s)
        return self._conn

    def request(self, method: str, path: str, json_body: Any = None,
                params: dict[str, Any] | None = None) -> Response:
        """Send one request; the response whatever its status."""
        url = path + ("?" + urlencode(params) if params else "")
        headers = {"Accept": "application/json, */*"}
        body: bytes | None = None
        if json_body is not None:
            body = json.dumps(json_body).encode()
            headers["Content-Type"] = "application/json"
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        for attempt in (1, 2):
            conn = self._connection()
            try:
                conn.request(method, url, body=body, headers=headers)
                r = conn.getresponse()
                return Response(method, path, r.status, r.read())
            except (http.client.RemoteDisconnected, ConnectionResetError, BrokenPipeError):
                self.close()
                if attempt == 2:
                    raise
        raise AssertionError("unreachable")

    def get(self, path: str, params: dict[str, Any] | None = None) -> Response:
        """GET `path`."""
        return self.request("GET", path, params=params)

    def post(self, path: str, json: Any = None) -> Response:
        """POST `path` with a JSON body."""
        return self.request("POST", path, json_body=json if json is not None else {})

    def close(self) -> None:
        """Close the connection (the next request opens another)."""
        if self._conn is not None:
            self._conn.close()
            self._conn = None


def _free_port(host: str) -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


@contextmanager
def serving(app: FastAPI, host: str = "127.0.0.1",
            start_timeout_s: float = 120.0) -> Iterator[ApiClient]:
    """Run `app` with uvicorn on a free loopback port in a thread (its lifespan starts
    the worker); yields a client for it; shuts the server down after."""
    port = _free_port(host)
    server = uvicorn.Server(uvicorn.Config(app, host=host, port=port, log_level="warning",
                                           lifespan="on"))
    thread = threading.Thread(target=server.run, name="exostudy-local-server", daemon=True)
    thread.start()
    # The lifespan builds default models on a first start: bounded by a generous limit,
    # and failing at once if the server thread gave up.
    deadline = time.monotonic() + start_timeout_s
    while not server.started:
        if not thread.is_alive():
            raise RuntimeError("the server failed to start (see the log above)")
        if time.monotonic() > deadline:
            server.should_exit = True
            raise RuntimeError(f"the server did not start within {start_timeout_s:.0f} s")
        time.sleep(0.05)
    client = ApiClient(host, port)
    try:
        yield client
    finally:
        client.close()
        server.should_exit = True
        thread.join(60.0)
