"""The `make run` set-up for the browser benchmarks, started in this process: a fresh
SQLite file with an experimenter, the server (uvicorn in a thread), the simulated
exoskeleton as its own UDP process, the worker; and the Chromium they drive.

Shared by bench/bench_live.py and bench/bench_console_load.py, so both measure the same
start-up and the same browser.
"""

from __future__ import annotations

import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import httpx  # noqa: E402
import uvicorn  # noqa: E402

from backend.core.config import Settings  # noqa: E402
from backend.main import create_app  # noqa: E402
from tests.login import PASSWORD, USERNAME, create_experimenter  # noqa: E402
from tests.polling import free_tcp_port, free_udp_port, wait_for  # noqa: E402

#: Chromium as the browser tests run it (Debian's, no download), never throttled.
CHROMIUM_ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu",
                 "--disable-background-networking", "--disable-renderer-backgrounding",
                 "--disable-background-timer-throttling"]


@dataclass(frozen=True)
class Running:
    """A started server: its base URL, a logged-in session cookie, its settings."""

    base: str
    cookies: dict[str, str]
    settings: Settings

    def health(self) -> dict[str, Any]:
        body: dict[str, Any] = httpx.get(f"{self.base}/api/health", cookies=self.cookies).json()
        return body


@contextmanager
def running_server(demo: bool = False, stream_rate: float | None = None,
                   ticks: int = 300) -> Iterator[Running]:
    """Start everything; yield once the worker has `ticks` ticks; stop it afterwards."""
    with tempfile.TemporaryDirectory() as d:
        url = f"sqlite:///{d}/bench.db"
        create_experimenter(url)
        port = free_tcp_port()
        settings = Settings(database_url=url, port=port, device_kind="udp",  # type: ignore[call-arg]
                            device_spawn_simulator=True,
                            device_address=f"127.0.0.1:{free_udp_port()}",
                            models_path=Path(d) / "models.json", utilities_dir=Path(d),
                            demo=demo, _env_file=None)
        if stream_rate is not None:
            settings = settings.model_copy(update={"stream_rate": stream_rate})
        server = uvicorn.Server(uvicorn.Config(create_app(settings), host="127.0.0.1", port=port,
                                               log_level="warning", ws="websockets-sansio"))
        thread = threading.Thread(target=server.run, daemon=True)
        thread.start()
        try:
            wait_for(lambda: server.started or not thread.is_alive(), 120, "the server",
                     poll=0.1)
            base = f"http://127.0.0.1:{port}"
            r = httpx.post(f"{base}/api/auth/login",
                           json={"username": USERNAME, "password": PASSWORD})
            running = Running(base, dict(r.cookies), settings)
            wait_for(lambda: running.health()["worker"]["ticks"] >= ticks, 120,
                     f"{ticks} ticks", poll=0.2)
            yield running
        finally:
            server.should_exit = True
            thread.join(20)


def launch_chromium(playwright: Any) -> Any:
    """Debian's Chromium through Playwright, as the browser tests launch it."""
    return playwright.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
