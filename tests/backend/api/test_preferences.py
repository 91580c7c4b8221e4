"""Preferences: asked through the participant link with blinded labels, stored once,
listed unblinded for the experimenter."""

from __future__ import annotations

from fastapi.testclient import TestClient


def _link(client: TestClient, *, preference: bool = True) -> tuple[int, str]:
    sid = client.post("/api/studies", json={"name": "Pref"}).json()["id"]
    pid = int(client.post(f"/api/studies/{sid}/participants", json={"code": "P3"}).json()["id"])
    for label, ctrl in (("A", "pec"), ("B", "umc")):
        client.post(f"/api/participants/{pid}/conditions",
                    json={"label": label, "controller": ctrl})
    body: dict[str, object] = {"preference": preference}
    if not preference:
        body["forms"] = [{"instrument_key": "sus", "condition_label": "A"}]
    r = client.post(f"/api/participants/{pid}/links", json=body)
    assert r.status_code == 201, r.text
    return pid, r.json()["token"]


def test_preference_with_blinded_labels(client: TestClient) -> None:
    pid, token = _link(client)
    participant = TestClient(client.app)
    view = participant.get(f"/api/participant-forms/{token}").json()
    assert view["forms"] == []
    assert view["preference"]["choices"] == ["A", "B", "none"]
    assert view["preference"]["question"] == "Which controller did you prefer?"
    url = f"/api/participant-forms/{token}/preference"
    r = participant.post(url, json={"choice": "umc"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "choice"]
    r = participant.post(url, json={"choice": "B"})
    assert r.status_code == 201 and r.json()["link_closed"] is True
    assert participant.post(url, json={"choice": "A"}).status_code == 410
    prefs = client.get(f"/api/participants/{pid}/preferences").json()
    assert [(p["choice"], p["controller"]) for p in prefs] == [("B", "umc")]


def test_no_preference_and_a_link_that_does_not_ask(client: TestClient) -> None:
    pid, token = _link(client)
    r = TestClient(client.app).post(f"/api/participant-forms/{token}/preference",
                                    json={"choice": "none"})
    assert r.status_code == 201
    assert client.get(f"/api/participants/{pid}/preferences").json()[0]["controller"] is None
    _, token = _link_without_preference(client)
    r = TestClient(client.app).post(f"/api/participant-forms/{token}/preference",
                                    json={"choice": "A"})
    assert r.status_code == 409 and r.json()["detail"].startswith("preference:")
    assert client.get("/api/participants/999/preferences").status_code == 404


def _link_without_preference(client: TestClient) -> tuple[int, str]:
    pid = client.get("/api/studies/1/participants").json()[0]["id"]
    r = client.post(f"/api/participants/{pid}/links",
                    json={"forms": [{"instrument_key": "sus", "condition_label": "A"}]})
    return pid, r.json()["token"]


def test_a_preference_needs_blinded_conditions(client: TestClient) -> None:
    sid = client.post("/api/studies", json={"name": "bare"}).json()["id"]
    pid = client.post(f"/api/studies/{sid}/participants", json={"code": "P9"}).json()["id"]
    r = client.post(f"/api/participants/{pid}/links", json={"preference": True})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "preference"]
