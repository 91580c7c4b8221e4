"""Concurrent writes of a study's montage and EMG settings: the request that loses the
race retries (or gets a 409), never a 500 (regressions: a concurrent PUT emg-montage hit
UNIQUE(study_id, version) and a concurrent first PUT emg-settings hit the primary key).
The race is made certain, not timed: another transaction commits the winner's row just
before the request flushes its own."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event, select
from sqlalchemy.orm import Session

from backend.db.emg import EmgAnalysisSettings, EmgMontage
from tests.backend.emg.test_emg_api import MONTAGE


@pytest.fixture
def race(client: TestClient) -> Iterator[list[Any]]:
    """Rows to commit from another session the first time a request's session flushes
    a new row of the same kind."""
    pending: list[Any] = []
    factory = client.app.state.sessions  # type: ignore[attr-defined]

    def before_flush(session: Session, _ctx: Any, _inst: Any) -> None:
        kinds = {type(o) for o in session.new}
        for row in [r for r in pending if type(r) in kinds]:
            pending.remove(row)
            with factory() as other:
                other.add(row)
                other.commit()

    event.listen(Session, "before_flush", before_flush)
    yield pending
    event.remove(Session, "before_flush", before_flush)


def test_a_montage_put_that_loses_the_race_takes_the_next_version(
        client: TestClient, race: list[Any]) -> None:
    study = client.post("/api/studies", json={"name": "race"}).json()["id"]
    race.append(EmgMontage(study_id=study, version=1, placement_scheme="other",
                           channels=MONTAGE["channels"]))
    r = client.put(f"/api/studies/{study}/emg-montage", json=MONTAGE)
    assert r.status_code == 200, r.text
    assert r.json()["version"] == 2
    versions = [m["version"] for m in client.get(f"/api/studies/{study}/emg-montages").json()]
    assert sorted(versions) == [1, 2]


def test_a_first_settings_put_that_loses_the_race_updates_the_winner(
        client: TestClient, race: list[Any]) -> None:
    study = client.post("/api/studies", json={"name": "race"}).json()["id"]
    race.append(EmgAnalysisSettings(study_id=study, processing={}, mains_hz=50))
    r = client.put(f"/api/studies/{study}/emg-settings",
                   json={"processing": {"envelope_hz": 4.0}, "mains_hz": 60})
    assert r.status_code == 200, r.text
    got = client.get(f"/api/studies/{study}/emg-settings").json()
    assert got["mains_hz"] == 60 and got["processing"]["envelope_hz"] == 4.0
    with client.app.state.sessions() as db:  # type: ignore[attr-defined]
        assert len(list(db.scalars(select(EmgAnalysisSettings)
                                   .where(EmgAnalysisSettings.study_id == study)))) == 1
