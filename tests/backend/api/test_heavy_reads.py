"""Reads of ticks beside a request's session are bounded (backend/api/deps.py): past
`HEAVY_READS` at once the answer is 503 with `Retry-After`, never a request left
holding one pooled connection while it waits for a second."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from backend.api.deps import HEAVY_READS, HEAVY_RETRY_S


def test_reads_past_the_bound_are_told_to_retry(client: TestClient) -> None:
    app: Any = client.app
    gate = app.state.heavy_reads
    study = client.post("/api/studies", json={"name": "Heavy"}).json()["id"]
    url = f"/api/studies/{study}/results"
    assert client.get(url).status_code == 200
    for _ in range(HEAVY_READS):  # as if that many reads were running
        assert gate.acquire(blocking=False)
    try:
        r = client.get(url)
        assert r.status_code == 503, r.text
        assert r.headers["retry-after"] == str(HEAVY_RETRY_S)
        assert "try again" in r.json()["detail"]
    finally:
        for _ in range(HEAVY_READS):
            gate.release()
    assert client.get(url).status_code == 200  # each request gave its place back
    assert gate.acquire(blocking=False)
    gate.release()
