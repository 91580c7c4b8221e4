"""The server with its real worker: health reports both alive, the WebSocket streams ticks,
and ticks reach the database."""

from __future__ import annotations

import json
import time

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from backend.core.config import Settings
from backend.db.engine import make_engine
from backend.db.models import ticks_table
from backend.main import create_app
from backend.schemas.live import STREAM_FIELDS
from tests.login import log_in
from tests.polling import wait_for

pytestmark = pytest.mark.slow


def _wait_healthy(client: TestClient, timeout: float = 60.0) -> dict:
    body: dict = wait_for(lambda: (b := client.get("/api/health").json())["status"] == "ok"
                          and b["worker"]["ticks"] > 50 and b, timeout,
                          "a healthy worker with 50 ticks", poll=0.2)
    return body


def test_health_websocket_and_storage(settings: Settings, experimenter: dict[str, str]) -> None:
    settings = settings.model_copy(update={"start_worker": True})
    with TestClient(create_app(settings)) as client:
        body = _wait_healthy(client)
        log_in(client, experimenter)
        assert body["worker"]["alive"] and body["device"]["alive"]
        assert isinstance(body["worker"]["pid"], int)
        assert body["worker"]["period_mean_ms"] is not None  # timing itself: see bench/

        with client.websocket_connect("/ws/live") as ws:
            first = json.loads(ws.receive_text())
            assert first["type"] == "status"
            seqs: list[int] = []
            # Until 150 samples came (the rate itself is bench/bench_live.py's); the
            # deadline only stops a stream that never delivers.
            deadline = time.monotonic() + 30.0
            while len(seqs) < 150:
                assert time.monotonic() < deadline, f"only {len(seqs)} samples streamed"
                msg = json.loads(ws.receive_text())
                if msg["type"] == "ticks":
                    columns = msg["columns"]
                    # Exactly the streamed columns, all of the same length.
                    assert list(columns) == list(STREAM_FIELDS)
                    assert {len(v) for v in columns.values()} == {len(columns["seq"])}
                    assert msg["sent_at"] >= max(columns["t_host"])
                    seqs.extend(columns["seq"])
            assert len(seqs) >= 150
            assert seqs == sorted(seqs)
        wait_for(lambda: client.get("/api/health").json()["database"]["ticks_written"] >= 150,
                 30, "150 ticks stored")
        engine = make_engine(settings.database_url)
        with engine.connect() as conn:
            stored = conn.execute(select(func.count()).select_from(ticks_table)).scalar_one()
        engine.dispose()
        assert stored >= 150


def test_websocket_refuses_a_caller_without_login(settings: Settings) -> None:
    from starlette.websockets import WebSocketDisconnect

    with TestClient(create_app(settings)) as client:
        with pytest.raises(WebSocketDisconnect) as refused, client.websocket_connect("/ws/live"):
            pass
        assert refused.value.code == 1008
        client.cookies.set("exostudy_session", "not-a-real-token")
        with pytest.raises(WebSocketDisconnect), client.websocket_connect("/ws/live"):
            pass


def test_changing_the_simulated_wearer_keeps_the_worker_and_checks_the_request(
        settings: Settings, experimenter: dict[str, str]) -> None:
    settings = settings.model_copy(update={"start_worker": True})
    with TestClient(create_app(settings)) as client:
        before = _wait_healthy(client)
        log_in(client, experimenter)
        run_before = before["database"]["current_run_id"]
        r = client.post("/api/worker/simulation",
                        json={"seed": 9, "script": "walking", "speed": 20})
        assert r.status_code == 200, r.text
        after = r.json()
        # Same process, a new run, counting from the new wearer's first sample.
        assert after["worker"]["pid"] == before["worker"]["pid"]
        assert after["worker"]["restarts"] == before["worker"]["restarts"]
        assert after["database"]["current_run_id"] != run_before
        assert after["device"]["alive"]
        # The new wearer streams (20 s of walking at 20x is ~2000 ticks a second).
        wait_for(lambda: client.get("/api/health").json()["worker"]["ticks"] > 500, 30,
                 "500 ticks of the new wearer")

        bad = client.post("/api/worker/simulation", json={"seed": 9, "script": "juggling"})
        assert bad.status_code == 422
        assert bad.json()["detail"].startswith("script:") and "walking" in bad.json()["detail"]
        too_fast = client.post("/api/worker/simulation",
                               json={"seed": 9, "script": "walking", "speed": 1000})
        assert too_fast.status_code == 422
        assert client.get("/api/health").json()["worker"]["pid"] == before["worker"]["pid"]
