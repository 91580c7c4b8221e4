"""LSL stream names (issue 23: a `'` in a subscribed name made the inlet spin at 92 % of a
core, and again after every restart): names are checked (422), the resolver query is
built only from checked text, an inlet that cannot resolve backs off and one that keeps
failing is closed and marked failed, and bad subscriptions stored earlier are closed at
start instead of resumed."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pylsl
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.core.config import Settings
from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.db.lab import MarkerStream
from backend.lab import marker_inlet
from backend.lab.marker_inlet import MarkerInlet
from backend.lsl import backoff
from backend.lsl import names as lsl_names
from backend.main import create_app
from tests.login import log_in
from tests.polling import wait_for
from tests.session_rows import evaluation_session


@pytest.mark.parametrize("text", ["Tobii:gaze@lab-pc", "openvibeMarkers", "EMG (left) #2"])
def test_ordinary_names_make_a_plain_query(text: str) -> None:
    assert lsl_names.problem(text) is None
    assert lsl_names.predicate("name", text) == f"name='{text}'"


@pytest.mark.parametrize("text", ["a'b", "x' or name='y", 'q"', "a]b", "a=b", "back\\slash",
                                  "", " lead", "x" * 201])
def test_text_that_could_change_the_query_is_refused(text: str) -> None:
    assert lsl_names.problem(text) is not None
    with pytest.raises(ValueError):
        lsl_names.predicate("source_id", text)


def _session(client: TestClient) -> int:
    sid = client.post("/api/studies", json={"name": "L"}).json()["id"]
    pid = client.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    r = client.post(f"/api/participants/{pid}/sessions",
                    json={"kind": "evaluation", "precompression_pct": 25})
    return int(r.json()["id"])


def test_the_api_refuses_a_quote_in_name_or_source_id(client: TestClient) -> None:
    sid = _session(client)
    url = f"/api/sessions/{sid}/marker-streams"
    for body, field in (({"name": "Mark'ers"}, "name"),
                        ({"name": "Markers", "source_id": "id'1"}, "source_id")):
        r = client.post(url, json=body)
        assert r.status_code == 422, r.text
        assert r.json()["detail"][0]["loc"] == ["body", field]
    assert client.get(url).json() == []


def _recording_resolver(calls: list[str]) -> Any:
    def resolve(query: str, **_: Any) -> list[Any]:
        calls.append(query)
        return []
    return resolve


def _inlet(name: str, source_id: str = "") -> tuple[MarkerInlet, list[str], list[float]]:
    failures: list[str] = []
    delays: list[float] = []
    inlet = MarkerInlet(7, name, source_id, lambda *_: None,
                        lambda _sub, why: failures.append(why))
    return inlet, failures, delays


def test_an_inlet_with_a_bad_name_fails_without_resolving(
        monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    monkeypatch.setattr(pylsl, "resolve_bypred", _recording_resolver(calls))
    inlet, failures, _ = _inlet("a'b")
    inlet.start()
    wait_for(lambda: not inlet.alive, 10, "the inlet to end")
    assert calls == [] and len(failures) == 1 and "a'b" in failures[0]


def test_a_resolver_that_returns_at_once_is_asked_with_backoff(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # liblsl answers a query it refuses at once with nothing: before, the inlet asked
    # again immediately, for ever.
    calls: list[str] = []
    monkeypatch.setattr(pylsl, "resolve_bypred", _recording_resolver(calls))
    inlet, _, delays = _inlet("Markers", "marker-src-1")
    waited = threading.Event()

    def sleep(seconds: float) -> bool:
        delays.append(seconds)
        if len(delays) >= 7:
            waited.set()
            inlet._stop.set()
            return True
        return False

    monkeypatch.setattr(inlet, "_sleep", sleep)
    inlet.start()
    assert waited.wait(10)
    wait_for(lambda: not inlet.alive, 10, "the inlet to stop")
    assert delays == [1.0, 2.0, 4.0, 8.0, 16.0, 30.0, 30.0]
    assert calls[0] == "source_id='marker-src-1'" and len(calls) == 7


def test_an_inlet_that_keeps_failing_is_closed_as_failed(
        monkeypatch: pytest.MonkeyPatch) -> None:
    class _Broken:
        def __init__(self, *_: Any, **__: Any) -> None:
            pass

        def open_stream(self, timeout: float) -> None:
            raise TimeoutError

        def close_stream(self) -> None:
            pass

    monkeypatch.setattr(pylsl, "resolve_bypred", lambda q, **_: [object()])
    monkeypatch.setattr(pylsl, "StreamInlet", _Broken)
    inlet, failures, delays = _inlet("Markers")

    def sleep(seconds: float) -> bool:
        delays.append(seconds)
        return False

    monkeypatch.setattr(inlet, "_sleep", sleep)
    inlet.start()
    wait_for(lambda: not inlet.alive, 10, "the inlet to give up")
    assert len(failures) == 1 and "failed attempts" in failures[0]
    assert len(delays) == marker_inlet.MAX_FAILURES - 1
    assert max(delays) <= backoff.BACKOFF_MAX_S


def test_bad_subscriptions_stored_before_are_closed_at_start(
        settings: Settings, experimenter: dict[str, str], tmp_path: Path) -> None:
    migrate.upgrade(settings.database_url)
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as db:
        session = evaluation_session(db)
        db.add_all([MarkerStream(session_id=session.id, name="x' or name='y", active=True),
                    MarkerStream(session_id=session.id, name="Markers", source_id="ok-1",
                                 active=True)])
        db.commit()
    off = settings.model_copy(update={"lsl_enabled": False, "device_spawn_simulator": False})
    with TestClient(create_app(off)) as client:
        log_in(client, experimenter)
        rows = {r.name: r for r in make_session_factory(engine)().scalars(
            select(MarkerStream))}
        assert not rows["x' or name='y"].active
        assert "not a name the LSL resolver can search for" in rows["x' or name='y"].error
        assert rows["Markers"].active and rows["Markers"].error == ""
        listed = client.get(f"/api/sessions/{rows['Markers'].session_id}/marker-streams")
        assert [s["error"] != "" for s in listed.json()] == [True, False]
    engine.dispose()
