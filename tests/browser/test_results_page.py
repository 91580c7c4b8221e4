"""The console's results page in a real browser: a finished PEC trial shows in the
tables and the trial list, the figures load, and the what-if replay answers side by
side without touching the stored trial."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest

from backend.core.config import Settings
from tests.browser.test_console import _api, _log_in, _ok, _session, _wait_ticks
from tests.live_server import running_server


@pytest.fixture
def fast_server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    fast = settings.model_copy(update={"start_worker": True, "device_speed": 5.0,
                                       "device_script": "squat-sequence"})
    with running_server(fast) as url:
        yield url


def test_results_page_shows_the_trial_figures_and_a_what_if(
    fast_server: str, page: Any, experimenter: dict[str, str]
) -> None:
    api = _api(fast_server, experimenter)
    study_id, session_id = _session(api, "evaluation")
    trials = _ok(api.post(f"/api/sessions/{session_id}/trials/plan",
                          json={"tasks": ["squat-sequence"]}))
    pec = next(t for t in trials if t["controller"] == "pec")
    _wait_ticks(api)
    _ok(api.post(f"/api/trials/{pec['id']}/start", json={}))
    time.sleep(5)  # 25 s of squats at 5x
    _ok(api.post(f"/api/trials/{pec['id']}/stop", json={"outcome": "completed"}))
    before = api.get(f"/api/trials/{pec['id']}/ticks.csv").text
    doc = _ok(api.get(f"/api/studies/{study_id}/results"))
    lifts = next(t for t in doc["trials"] if t["trial_id"] == pec["id"])["lifts"]
    assert lifts >= 1

    _log_in(page, fast_server, f"/console/studies/{study_id}", experimenter)
    page.click("#results-link")
    page.wait_for_url(f"**/console/studies/{study_id}/results")
    page.wait_for_function("window.exostudyResults.loaded >= 1", timeout=30000)
    row = page.locator(f"#trials tr[data-trial='{pec['id']}']")
    cells = row.locator("td").all_inner_texts()
    assert cells[1:5] == ["P01", "PEC", "squat-sequence", "simulation"]
    assert int(cells[5]) == lifts
    # The false-positive table has a PEC row; the performance table (UMC and E-UMC
    # only, as in the paper) has no participant column yet.
    assert "PEC" in page.inner_text("section[data-table=false_positives]")
    header = page.locator("section[data-table=performance] th").all_inner_texts()
    assert "P01" not in header
    for name in ("peak_torques", "onset_to_lock"):
        page.wait_for_function(
            f"document.querySelector('figure[data-figure={name}] img').naturalWidth > 0",
            timeout=30000)

    row.locator("button.open").click()
    assert page.get_attribute("#panel-replay", "href") == f"/live?trial={pec['id']}"
    page.wait_for_function("document.querySelector('#panel-timeline').naturalWidth > 0",
                           timeout=30000)
    # The segment editor: a proposal from the automatic segmentation (labels from the
    # simulation here), saved as the experimenter's list.
    page.wait_for_function("window.exostudyResults.segments === 0")
    page.click("#seg-propose")
    page.wait_for_function("window.exostudyResults.segments > 0", timeout=30000)
    proposed = page.evaluate("window.exostudyResults.segments")
    page.click("#seg-save")
    page.wait_for_selector("#seg-msg.msg-ok", timeout=30000)
    stored = _ok(api.get(f"/api/trials/{pec['id']}/segments"))
    assert len(stored) == proposed and {s["source"] for s in stored} == {"edited"}
    assert {s["label"] for s in stored} <= {"squat", "unlabelled"}

    page.select_option("#whatif-controller", "pec")
    page.fill("input[name=rate_hz]", "10")
    page.click("#whatif-run")
    page.wait_for_function("window.exostudyResults.whatIf !== null", timeout=60000)
    r = page.evaluate("window.exostudyResults.whatIf")
    assert r["original"]["lifts"] == r["replay"]["lifts"] == lifts
    shown = page.locator("#whatif tr[data-metric=lifts] td").all_inner_texts()
    assert shown == ["lifts", str(lifts), str(lifts)]
    assert api.get(f"/api/trials/{pec['id']}/ticks.csv").text == before
