"""A real server for end-to-end tests: uvicorn in a thread, the worker as a real process."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

import uvicorn

from backend.core.config import Settings
from backend.main import create_app
from tests.polling import free_tcp_port, wait_for


@contextmanager
def running_server(settings: Settings) -> Iterator[str]:
    """Start the app on a free port; yields its base URL; stops it (and the worker) after."""
    port = free_tcp_port()
    settings = settings.model_copy(update={"host": "127.0.0.1", "port": port})
    config = uvicorn.Config(create_app(settings), host="127.0.0.1", port=port,
                            log_level="warning", ws="websockets-sansio")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="uvicorn", daemon=True)
    thread.start()
    wait_for(lambda: server.started or not thread.is_alive(), 30, "the server to start")
    if not server.started:
        raise RuntimeError("server did not start")
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(20)
