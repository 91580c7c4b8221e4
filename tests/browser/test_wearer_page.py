"""The per-wearer page in a real browser: three seeded long-use sessions of a real study
show their values, intervals and trends as the hand counts give them; the page starts
the controller in a long-use session on the running worker, marks an event and stops it;
and a screenshot of the progress is taken for the docs.

`EXOSTUDY_DOCS_IMAGES=1` writes the screenshot to docs/img/wearer-progress.png (how the
docs image is made: `make docs-images`); it always goes to test-artifacts/."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from backend.core.config import Settings
from backend.db.engine import make_engine
from tests.backend.long_use_data import add_long_use_trial
from tests.browser.conftest import ARTIFACTS
from tests.browser.login_page import log_in_through
from tests.browser.test_console import _api, _ok, _wait_ticks
from tests.live_server import running_server

DOCS_IMAGE = Path(__file__).resolve().parents[2] / "docs" / "img" / "wearer-progress.png"


@pytest.fixture
def fast_server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    fast = settings.model_copy(update={"start_worker": True, "device_speed": 5.0,
                                       "device_script": "squat-sequence"})
    with running_server(fast) as url:
        yield url


def _cell(page: Any, metric: str, session: int | None = None) -> tuple[str, str]:
    """(value, interval) as a cell of the progress table shows them; the trend's
    without `session`."""
    sel = (f"#progress-table td[data-metric={metric}][data-session='{session}']"
           if session is not None else f"#progress-table td.trend[data-metric={metric}]")
    cell = page.locator(sel)
    return cell.locator(".value").inner_text(), cell.locator(".ci").inner_text()


def test_wearer_page_shows_the_learning_curves_and_runs_long_use(
    fast_server: str, page: Any, experimenter: dict[str, str], settings: Settings
) -> None:
    api = _api(fast_server, experimenter)
    study = _ok(api.post("/api/studies", json={"name": "Long use at work"}))["id"]
    pid = _ok(api.post(f"/api/studies/{study}/participants", json={"code": "W01"}))["id"]
    sessions = [_ok(api.post(f"/api/participants/{pid}/sessions", json={
        "kind": "long_use", "precompression_pct": 25,
        "started_at": f"2026-12-0{d}T09:00:00Z"}))["id"] for d in (1, 2, 3)]
    engine = make_engine(settings.database_url)
    seeded = [add_long_use_trial(engine, s, correct, 5 - correct, locks)
              for s, correct, locks in zip(sessions, (2, 3, 4), (3, 2, 1), strict=True)]

    log_in_through(page, fast_server, f"/console/participants/{pid}/progress", experimenter)
    page.wait_for_function("window.exostudyWearer.loaded >= 1", timeout=30000)
    assert page.inner_text("#wearer-code") == "W01"
    assert page.locator("#progress-table thead th").all_inner_texts() == [
        "metric", "session 1", "session 2", "session 3", "trend per session [95 %]"]
    # Lock and recognition rates: 2, 3, 4 of 5 confirmed squats (Wilson intervals).
    assert [_cell(page, "lock_rate", s)[0] for s in (1, 2, 3)] == ["40 %", "60 %", "80 %"]
    assert _cell(page, "lock_rate", 1)[1] == "[12, 77]"  # Wilson 2/5: 0.1176..0.7693
    assert _cell(page, "lock_rate") == ("+20.0 pp per session", "[20.0, 20.0]")
    assert _cell(page, "recognition_rate", 3)[0] == "80 %"
    # Every lock 0.3 s after onset: flat, slope 0 inside its interval.
    assert [_cell(page, "time_to_lock_s", s)[0] for s in (1, 2, 3)] == ["0.30 s"] * 3
    assert _cell(page, "time_to_lock_s") == ("+0.000 s per session", "[0.000, 0.000]")
    # Walking false positives: 3, 2, 1 in 9.99 s of walking each (markers).
    hours = seeded[0].walking_hours
    shown = [_cell(page, "fp_per_hour_walking", s)[0] for s in (1, 2, 3)]
    assert shown == [f"{k / hours:.1f}" for k in (3, 2, 1)]
    assert _cell(page, "fp_per_hour_walking")[0] == f"{-1 / hours:.2f} /h per session"
    # No stairs bout in any session: nothing to show, no trend.
    assert _cell(page, "fp_per_hour_stairs", 1) == ("–", "")
    assert _cell(page, "fp_per_hour_stairs")[0] == "–"
    # Six lifts (five confirmed squats, one unlabelled segment) in 40 s of use.
    assert _cell(page, "lifts_per_hour", 2)[0] == f"{6 / seeded[0].hours:.1f}"
    rows = page.locator("#progress-sessions tbody tr")
    assert rows.count() == 3
    assert rows.nth(0).locator("td").all_inner_texts()[5:8] == ["6", "5", "1"]
    assert page.locator("#curves figure").count() == 6
    assert page.locator("figure[data-curve=lock_rate] circle.point").count() == 3
    assert page.locator("figure[data-curve=lock_rate] line.trend").count() == 1

    if os.environ.get("EXOSTUDY_DOCS_IMAGES"):
        page.locator("section.card").nth(1).screenshot(path=str(DOCS_IMAGE))
    ARTIFACTS.mkdir(exist_ok=True)
    page.locator("section.card").nth(1).screenshot(path=str(ARTIFACTS / "wearer-progress.png"))

    # Long use from the page, in the newest session: the PEC runs, an event is marked
    # while it runs, the experimenter stops it.
    assert page.input_value("#use-session") == str(sessions[2])
    _wait_ticks(api)
    page.select_option("#use-controller", "pec")
    page.click("#use-start")
    page.wait_for_function("document.querySelector('#use-status').dataset.running !== ''",
                           timeout=30000)
    running = int(page.get_attribute("#use-status", "data-running"))
    _wait_ticks(api, 300, controller="pec")
    page.locator("#marker-bar button.marker-button").first.click()
    page.wait_for_selector("#marker-msg.msg-ok", timeout=30000)
    page.click("#use-stop")
    page.wait_for_function("document.querySelector('#use-status').dataset.running === ''",
                           timeout=30000)
    trial = _ok(api.get(f"/api/trials/{running}"))
    assert trial["task"] == "long_use" and trial["status"] == "completed"
    stored = _ok(api.get(f"/api/trials/{running}/ticks.json"))["columns"]["t"]
    assert trial["tick_count"] == len(stored) > 0
    marks = [m for m in _ok(api.get(f"/api/trials/{running}/markers"))
             if m["source"] == "console"]
    assert len(marks) == 1 and marks[0]["session_id"] == sessions[2]
    # The new trial joins session 3 (all controllers); the UMC filter shows the seeded.
    page.wait_for_function("window.exostudyWearer.doc.sessions[2].trial_ids.length === 2",
                           timeout=30000)
    third = page.locator("#progress-sessions tbody tr").nth(2).locator("td")
    assert third.nth(2).inner_text() == "PEC, UMC"
    before = page.evaluate("window.exostudyWearer.loaded")
    page.select_option("#progress-controller", "umc")
    page.wait_for_function(f"window.exostudyWearer.loaded > {before}", timeout=30000)
    assert [_cell(page, "lock_rate", s)[0] for s in (1, 2, 3)] == ["40 %", "60 %", "80 %"]
