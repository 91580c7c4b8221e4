"""The embedded default of `make run`: the simulated exoskeleton as its own process on
UDP, the worker talking to it over loopback, and what happens when the device dies."""

from __future__ import annotations

import socket
import time

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.models import ticks_table
from backend.main import create_app

pytestmark = pytest.mark.slow


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_device_process_over_udp_then_device_loss(settings: Settings) -> None:
    port = _free_udp_port()
    settings = settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
        "device_address": f"127.0.0.1:{port}",
    })
    with TestClient(create_app(settings)) as client:
        deadline = time.monotonic() + 60
        body: dict = {}
        while time.monotonic() < deadline:
            body = client.get("/api/health").json()
            if body["status"] == "ok" and body["worker"]["ticks"] > 100:
                break
            time.sleep(0.2)
        assert body["device"] == {**body["device"], "alive": True, "kind": "udp"}
        assert body["worker"]["gaps"] == 0

        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        runtime.device_process.kill()
        killed = time.monotonic()
        while client.get("/api/health").json()["device"]["alive"]:
            assert time.monotonic() - killed < 2.0, "device loss not noticed"
            time.sleep(0.05)
        after = client.get("/api/health").json()
        assert after["worker"]["alive"]  # the worker survives a lost device
        assert after["status"] == "degraded"
        time.sleep(settings.db_flush_interval + 0.3)

    engine = make_engine(settings.database_url)
    with engine.connect() as conn:
        stored = conn.execute(select(func.count()).select_from(ticks_table)).scalar_one()
    engine.dispose()
    assert stored >= 100
