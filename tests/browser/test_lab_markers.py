"""Event markers in a real browser: a hotkey on the live page stores a marker at the
newest tick, the plots draw it, and the study export carries it."""

from __future__ import annotations

import csv
import io
import time
import zipfile
from typing import Any

import httpx
import pylsl

from tests.browser.login_page import log_in_through
from tests.polling import wait_for


def _ok(r: httpx.Response) -> Any:
    assert r.is_success, r.text
    return r.json()


def _until(page: Any, expression: str, timeout: float) -> None:
    """Poll a page expression (page.evaluate runs over the DevTools protocol, so the
    pages' Content-Security-Policy, which forbids eval, does not stop it)."""
    wait_for(lambda: page.evaluate(expression), timeout, expression, poll=0.1)


def test_a_marker_hotkey_marks_the_plot_and_the_export(
        page: Any, server: str, experimenter: dict[str, str]) -> None:
    api = httpx.Client(base_url=server, timeout=30)
    token = _ok(api.post("/api/auth/token", json=experimenter))["access_token"]
    api.headers["Authorization"] = f"Bearer {token}"
    study = _ok(api.post("/api/studies", json={"name": "marker study"}))
    pid = _ok(api.post(f"/api/studies/{study['id']}/participants", json={"code": "P01"}))["id"]
    sess = _ok(api.post(f"/api/participants/{pid}/sessions",
                        json={"kind": "evaluation", "precompression_pct": 25}))
    bad = api.put(f"/api/studies/{study['id']}/marker-labels",
                  json={"labels": ["pause", " pause "]})
    assert bad.status_code == 422 and "different" in bad.text

    log_in_through(page, server, "/live", experimenter)
    # The study page sets the study's labels (the hotkeys' order).
    page.goto(f"{server}/console/studies/{study['id']}")
    page.locator("#marker-labels-input").wait_for(timeout=15_000)
    _until(page, "document.querySelector('#marker-labels-input').value.includes('note')", 15)
    page.fill("#marker-labels-input", "box dropped, participant paused")
    page.click("#marker-labels-save")
    page.locator("#marker-labels-msg", has_text="saved 2 labels").wait_for(timeout=10_000)
    assert _ok(api.get(f"/api/studies/{study['id']}/marker-labels"))["labels"] == [
        "box dropped", "participant paused"]
    page.goto(f"{server}/live?session={sess['id']}")
    _until(page, "window.exostudyMarkers && window.exostudyMarkers.labels.length === 2"
           " && window.exostudyLive.samples > 50", 60)
    assert page.locator("#marker-bar .marker-button").count() == 2
    page.keyboard.press("2")
    _until(page, "window.exostudyMarkers.stored.length === 1 || document.querySelector("
           "'#marker-msg').textContent.includes('not stored')", 10)
    assert "not stored" not in page.inner_text("#marker-msg"), page.inner_text("#marker-msg")
    # Drawn on the live plots once the stream brings it back.
    _until(page, "window.exostudyMarkers.drawn.includes('participant paused')", 10)
    stored = page.evaluate("window.exostudyMarkers.stored[0]")
    assert stored["label"] == "participant paused" and stored["source"] == "console"
    assert stored["t"] is not None and stored["session_id"] == sess["id"]
    # Typing in the note field is not a hotkey.
    page.fill("#marker-note", "12")
    page.click("#marker-free")
    _until(page, "window.exostudyMarkers.stored.length === 2", 10)
    assert page.evaluate("window.exostudyMarkers.stored[1]")["note"] == "12"

    # The session page: the same buttons, and other software's marker streams to pick.
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(
        "BrowserTestMarkers", "Markers", 1, pylsl.IRREGULAR_RATE, pylsl.cf_string,
        f"browser-test-{sess['id']}-{time.time_ns()}"))
    page.goto(f"{server}/console/sessions/{sess['id']}")
    _until(page, "window.exostudySession && window.exostudySession.ready === true", 30)
    assert page.locator("#marker-bar .marker-button").count() == 2
    page.click("#lsl-find")
    page.locator("#lsl-found li", has_text="BrowserTestMarkers").get_by_role(
        "button", name="Listen").click(timeout=15_000)
    page.locator("#lsl-subs li", has_text="BrowserTestMarkers").wait_for(timeout=10_000)
    subs = _ok(api.get(f"/api/sessions/{sess['id']}/marker-streams"))
    assert [s["name"] for s in subs] == ["BrowserTestMarkers"] and subs[0]["active"]
    del outlet

    z = api.get(f"/api/studies/{study['id']}/export.zip")
    assert z.status_code == 200
    rows = list(csv.DictReader(io.StringIO(
        zipfile.ZipFile(io.BytesIO(z.content)).read("markers.csv").decode())))
    assert [r["label"] for r in rows] == ["participant paused", "note"]
    assert float(rows[0]["t"]) == stored["t"] and rows[1]["note"] == "12"
