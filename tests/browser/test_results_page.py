"""The console's results page in a real browser: a finished PEC trial shows in the
tables and the trial list, the questionnaire table marks each participant's higher
score, the tables sort and filter, the figures load, and the what-if replay answers side
by side without touching the stored trial."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from backend.core.config import Settings
from tests.browser.login_page import log_in_through
from tests.browser.test_console import _api, _ok, _pec_trial, _session
from tests.live_server import running_server


@pytest.fixture
def fast_server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    fast = settings.model_copy(update={"start_worker": True, "device_speed": 5.0,
                                       "device_script": "squat-sequence"})
    with running_server(fast) as url:
        yield url


def _sus(answers: list[int]) -> float:
    """The SUS formula (Brooke 1996), written out independently of the server's."""
    return 2.5 * (sum(a - 1 for a in answers[0::2]) + sum(5 - a for a in answers[1::2]))


def _answer_sus(api: httpx.Client, participant_id: int, answers: dict[str, list[int]],
                preferred: str | None) -> None:
    """The participant fills in the SUS for each blinded label (and the preference)
    through a link, as the form page does."""
    link = _ok(api.post(f"/api/participants/{participant_id}/links", json={
        "forms": [{"instrument_key": "sus", "condition_label": label} for label in answers],
        "preference": preferred is not None}))
    anonymous = httpx.Client(base_url=str(api.base_url))
    for i, values in enumerate(answers.values()):
        _ok(anonymous.post(f"{link['api_path']}/responses", json={
            "form": i, "answers": {f"q{k}": v for k, v in enumerate(values, start=1)}}))
    if preferred is not None:
        _ok(anonymous.post(f"{link['api_path']}/preference", json={"choice": preferred}))


def _column(page: Any, table: str, name: str) -> list[Any]:
    """One column of a table as the page shows it (after filters and sorting)."""
    return page.evaluate(f"""(() => {{ const t = window.exostudyResults.tables[{table!r}];
        const i = t.header.indexOf({name!r}); return t.rows.map(r => r[i]); }})()""")


def test_results_page_shows_the_trial_figures_and_a_what_if(
    fast_server: str, page: Any, experimenter: dict[str, str]
) -> None:
    api = _api(fast_server, experimenter)
    study_id, session_id = _session(api, "evaluation")
    pec = {"id": _pec_trial(api, session_id, 2500)}  # 25 s of squats
    before = api.get(f"/api/trials/{pec['id']}/ticks.csv").text
    doc = _ok(api.get(f"/api/studies/{study_id}/results"))
    lifts = next(t for t in doc["trials"] if t["trial_id"] == pec["id"])["lifts"]
    assert lifts >= 1

    # SUS answers: P01 (the trial's participant) rates the UMC higher and prefers it;
    # P02, who ran no trial here, rates the PEC higher.
    p01 = _ok(api.get(f"/api/studies/{study_id}/participants"))[0]["id"]
    key01 = {c["controller"]: c["label"]
             for c in _ok(api.get(f"/api/participants/{p01}/conditions"))}
    answers01 = {"umc": [5, 1, 4, 2, 5, 1, 4, 2, 5, 1], "pec": [3, 2, 4, 3, 3, 2, 4, 2, 3, 3]}
    _answer_sus(api, p01, {key01[c]: a for c, a in answers01.items()}, key01["umc"])
    p02 = _ok(api.post(f"/api/studies/{study_id}/participants", json={"code": "P02"}))["id"]
    for label, ctl in (("A", "pec"), ("B", "umc")):
        _ok(api.post(f"/api/participants/{p02}/conditions",
                     json={"label": label, "controller": ctl}))
    answers02 = {"pec": [4, 2, 4, 2, 4, 1, 4, 2, 4, 2], "umc": [4, 2, 3, 2, 4, 2, 3, 2, 4, 2]}
    _answer_sus(api, p02, {"A": answers02["pec"], "B": answers02["umc"]}, None)
    sus = {("P01", c): _sus(a) for c, a in answers01.items()}
    sus |= {("P02", c): _sus(a) for c, a in answers02.items()}
    assert sus[("P01", "umc")] > sus[("P01", "pec")] and sus[("P02", "pec")] > sus[("P02", "umc")]

    log_in_through(page, fast_server, f"/console/studies/{study_id}", experimenter)
    # The page's script sets the link's target; a click before that follows "#".
    page.wait_for_selector(f"#results-link[href='/console/studies/{study_id}/results']")
    page.click("#results-link")
    page.wait_for_url(f"**/console/studies/{study_id}/results")
    page.wait_for_function("window.exostudyResults.loaded >= 1", timeout=30000)
    row = page.locator(f"#trials tr[data-trial='{pec['id']}']")
    cells = row.locator("td").all_inner_texts()
    assert cells[1:5] == ["P01", "PEC", "squat-sequence", "simulation"]
    assert int(cells[5]) == lifts
    assert row.locator("a.replay-link").get_attribute("href") == f"/live?trial={pec['id']}"
    assert row.locator("a.timeline-link").get_attribute("href") == (
        f"/api/trials/{pec['id']}/figures/timeline.svg")
    assert page.get_attribute("#export", "href") == f"/api/studies/{study_id}/export.zip"
    # The false-positive table has a PEC row; the performance table (UMC and E-UMC
    # only, as in the paper) has no participant column yet.
    assert "PEC" in page.inner_text("section[data-table=false_positives]")
    header = page.locator("section[data-table=performance] th").all_inner_texts()
    assert "P01" not in header

    # Questionnaires in the paper's layout: a column per participant, each one's
    # higher SUS score marked, the stated preference unblinded.
    q = page.evaluate("window.exostudyResults.tables.questionnaires")
    assert q["header"] == ["Instrument", "Controller", "P01", "P02"]
    by_ctl = {r[1]: r[2:] for r in q["rows"]}
    assert by_ctl["UMC"] == [f"**{sus[('P01', 'umc')]:g}**", f"{sus[('P02', 'umc')]:g}"]
    assert by_ctl["PEC"] == [f"{sus[('P01', 'pec')]:g}", f"**{sus[('P02', 'pec')]:g}**"]
    assert by_ctl[""] == ["UMC", "/"]  # the preference row
    marked = page.locator("section[data-table=questionnaires] strong.highest").all_inner_texts()
    assert sorted(marked) == sorted([f"{sus[('P01', 'umc')]:g}", f"{sus[('P02', 'pec')]:g}"])

    # Filters: one participant's column; one controller's rows (the trial list follows).
    page.select_option("#filter-participant", "P01")
    q = page.evaluate("window.exostudyResults.tables.questionnaires")
    assert q["header"] == ["Instrument", "Controller", "P01"]
    assert page.locator("section[data-table=questionnaires] strong.highest"
                        ).all_inner_texts() == [f"{sus[('P01', 'umc')]:g}"]
    page.select_option("#filter-participant", "")
    page.select_option("#filter-controller", "umc")
    q = page.evaluate("window.exostudyResults.tables.questionnaires")
    assert [r[1] for r in q["rows"]] == ["UMC", ""]
    assert page.evaluate("window.exostudyResults.trials") == []
    assert page.locator(f"#trials tr[data-trial='{pec['id']}']").count() == 0
    page.select_option("#filter-controller", "")
    assert page.evaluate("window.exostudyResults.trials") == [pec["id"]]

    # Every count, one row each: the questionnaire scores sort by a header press.
    page.select_option("#layout", "long")
    section = page.locator("section[data-table=questionnaires]")
    section.locator("th button.sort", has_text="score").click()
    scores = [float(v) for v in _column(page, "questionnaires", "score")]
    assert scores == sorted(sus.values())
    section = page.locator("section[data-table=questionnaires]")
    section.locator("th button.sort", has_text="score").click()
    assert [float(v) for v in _column(page, "questionnaires", "score")] == sorted(
        sus.values(), reverse=True)
    assert section.locator("th[aria-sort=descending]").inner_text().startswith("score")

    # Per-lift outcomes: one row per lift of the trial, sorted by onset, latest first.
    page.click("#lifts-details summary")
    assert _column(page, "lifts", "participant") == ["P01"] * lifts
    assert _column(page, "lifts", "controller") == ["pec"] * lifts
    page.locator("#lifts th button.sort", has_text="start").click()
    page.locator("#lifts th button.sort", has_text="start").click()
    starts = [int(v) for v in _column(page, "lifts", "start")]
    assert starts == sorted(starts, reverse=True) and len(set(starts)) == lifts
    shown = page.locator("#lifts tbody tr td:nth-child(6)").all_inner_texts()
    assert [int(v) for v in shown] == starts

    for name in ("peak_torques", "onset_to_lock"):
        page.wait_for_function(
            f"document.querySelector('figure[data-figure={name}] img').naturalWidth > 0",
            timeout=30000)
        for fmt in ("png", "svg"):
            link = page.locator(f"figure[data-figure={name}] a", has_text=fmt.upper())
            assert link.get_attribute("href") == f"/api/studies/{study_id}/figures/{name}.{fmt}"

    row = page.locator(f"#trials tr[data-trial='{pec['id']}']")
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

    # What if the PEC had run at 10 Hz: both columns score the same lifts.
    page.select_option("#whatif-controller", "pec")
    page.fill("input[name=rate_hz]", "10")
    page.click("#whatif-run")
    page.wait_for_function("window.exostudyResults.whatIf !== null", timeout=60000)
    r = page.evaluate("window.exostudyResults.whatIf")
    assert r["original"]["lifts"] == r["replay"]["lifts"] == lifts
    assert r["replay_config"]["settings"]["pec_rate_hz"] == 10
    shown = page.locator("#whatif tr[data-metric=lifts] td").all_inner_texts()
    assert shown == ["lifts", str(lifts), str(lifts), "same"]
    ticks = page.locator("#whatif tr[data-metric=ticks] td").all_inner_texts()
    assert ticks[1:3] == [str(r["original"]["ticks"]), str(r["replay"]["ticks"])]
    assert "at 10 Hz" in page.inner_text("#whatif thead")
    assert api.get(f"/api/trials/{pec['id']}/ticks.csv").text == before
