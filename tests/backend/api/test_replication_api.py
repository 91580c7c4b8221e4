"""The replication API: nothing before a report, a background job with progress, then
the newest report's claims, its HTML page and figures; bad requests are 4xx."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from tests.polling import wait_for

pytestmark = pytest.mark.slow


@pytest.fixture
def rclient(settings: Settings, experimenter: dict[str, str],
            tmp_path: Path) -> Iterator[TestClient]:
    from backend.main import create_app
    from tests.login import log_in

    quiet = settings.model_copy(update={"device_spawn_simulator": False,
                                        "run_dir": tmp_path})
    with TestClient(create_app(quiet)) as c:
        log_in(c, experimenter)
        yield c


def test_replication_runs_as_a_job_and_serves_its_report(rclient: TestClient) -> None:
    empty = rclient.get("/api/replication")
    assert empty.status_code == 200 and empty.json() == {"job": None, "report": None}
    missing = rclient.get("/api/replication/report")
    assert missing.status_code == 404 and "POST /api/replication" in missing.text
    bad = rclient.post("/api/replication", json={"seeds": 1})
    assert bad.status_code == 422 and "seeds" in bad.text
    r = rclient.post("/api/replication", json={"seeds": 2, "participants": 2})
    assert r.status_code == 202, r.text
    job_id = r.json()["job_id"]

    def finished() -> dict[str, object] | None:
        got = rclient.get("/api/replication").json()
        job = got["job"]
        return got if job["id"] == job_id and job["status"] in ("done", "failed") else None

    got = wait_for(finished, 600.0, "the replication job to finish", poll=0.5)
    assert got is not None and got["job"]["status"] == "done", got["job"]  # type: ignore[index]
    report = got["report"]
    assert report is not None
    verdicts = {c["key"]: c["verdict"] for c in report["claims"]}  # type: ignore[index]
    assert verdicts["questionnaires"] == "not simulated"
    assert verdicts["chi_square"] == "reproduced"
    page = rclient.get("/api/replication/report")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "claim by claim" in page.text
    png = rclient.get("/api/replication/figures/peak_torques.png")
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
    assert rclient.get("/api/replication/figures/nope.svg").status_code == 404
    assert rclient.get("/api/replication/figures/Bad-Name.png").status_code == 422
    assert rclient.get("/console/replication").status_code == 200
