"""The cohort API: a background job with progress, then the analysis, tables and figures
rendered from the stored document; bad requests are 4xx naming the field."""

from __future__ import annotations

import csv
import io

import pytest
from fastapi.testclient import TestClient

from tests.polling import wait_for

pytestmark = pytest.mark.slow


def _wait(client: TestClient, cohort_id: int, limit_s: float = 300.0) -> dict[str, object]:
    seen: list[float] = []

    def finished() -> dict[str, object] | None:
        got = client.get(f"/api/cohorts/{cohort_id}").json()
        seen.append(got["progress"])
        return dict(got) if got["status"] in ("ready", "failed") else None

    got = wait_for(finished, limit_s, f"cohort {cohort_id} to finish", poll=0.1)
    assert seen == sorted(seen)  # progress only moves forward
    return got


def test_a_cohort_runs_as_a_job_and_serves_its_analysis(client: TestClient) -> None:
    r = client.post("/api/cohorts", json={"participants": 3, "seed": 4,
                                          "controllers": ["umc", "pec"]})
    assert r.status_code == 202, r.text
    cohort = r.json()
    assert cohort["status"] == "queued" and cohort["job_id"]
    # Not ready yet (or just done): tables refuse with 409 until then, never 5xx.
    early = client.get(f"/api/cohorts/{cohort['id']}/tables/metrics.csv")
    assert early.status_code in (200, 409)
    got = _wait(client, cohort["id"])
    assert got["status"] == "ready", got["error"]
    assert got["wall_s"] > 0 and got["progress"] == 1.0
    doc = got["result"]
    assert len(doc["participants"]) == 3 and doc["config"]["controllers"] == ["umc", "pec"]
    assert {c["metric"] for c in doc["comparisons"]} >= {"fp_total", "support_asymmetry_nm"}

    table = client.get(f"/api/cohorts/{cohort['id']}/tables/participants.csv")
    assert table.status_code == 200 and table.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(table.text)))
    assert len(rows) == 6
    # The served table is the stored document's numbers.
    first = doc["participants"][0]["metrics"]["umc"]["fp_total"]
    assert float(rows[0]["fp_total"]) == first
    md = client.get(f"/api/cohorts/{cohort['id']}/tables/comparisons.md")
    assert md.status_code == 200 and "Wilcoxon" in md.text
    png = client.get(f"/api/cohorts/{cohort['id']}/figures/power.png")
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
    svg = client.get(f"/api/cohorts/{cohort['id']}/figures/distributions.svg")
    assert svg.status_code == 200 and b"<svg" in svg.content[:500]
    listed = client.get("/api/cohorts").json()
    assert listed[0]["id"] == cohort["id"] and listed[0]["result"] is None


def test_bad_cohort_requests_name_what_is_wrong(client: TestClient) -> None:
    r = client.post("/api/cohorts", json={"participants": 3, "controllers": ["umc", "lqr"]})
    assert r.status_code == 422 and "lqr" in r.text
    r = client.post("/api/cohorts", json={"participants": 100_000})
    assert r.status_code == 422 and "participants" in r.text
    r = client.post("/api/cohorts", json={"participants": 3, "bogus": 1})
    assert r.status_code == 422 and "bogus" in r.text
    assert client.get("/api/cohorts/999").status_code == 404
    assert client.get("/api/cohorts/1/tables/nope.csv").status_code in (404, 422)
    assert client.get("/api/cohorts").json() == []  # nothing was stored
