"""The embedded default of `make run`: the simulated exoskeleton as its own process on
UDP, the worker talking to it over loopback, and what happens when the device dies."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.models import ticks_table
from backend.main import create_app
from tests.polling import free_udp_port, wait_for

pytestmark = pytest.mark.slow


def test_device_process_over_udp_then_device_loss(settings: Settings) -> None:
    port = free_udp_port()
    settings = settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
        "device_address": f"127.0.0.1:{port}",
    })
    with TestClient(create_app(settings)) as client:
        body = wait_for(lambda: (b := client.get("/api/health").json())["status"] == "ok"
                        and b["worker"]["ticks"] > 100 and b, 60, "100 ticks from the device")
        assert body["device"] == {**body["device"], "alive": True, "kind": "udp"}
        assert body["worker"]["gaps"] == 0

        runtime = client.app.state.runtime  # type: ignore[attr-defined]
        runtime.device_process.kill()
        # How soon the loss shows is measured by bench/bench_faults.py (`--only device`).
        wait_for(lambda: not client.get("/api/health").json()["device"]["alive"], 30,
                 "the device loss to show in health")
        after = client.get("/api/health").json()
        assert after["worker"]["alive"]  # the worker survives a lost device
        assert after["status"] == "degraded"
        wait_for(lambda: runtime.recorder.written >= 100, 30, "100 ticks stored")

    engine = make_engine(settings.database_url)
    with engine.connect() as conn:
        stored = conn.execute(select(func.count()).select_from(ticks_table)).scalar_one()
    engine.dispose()
    assert stored >= 100
