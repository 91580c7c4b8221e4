"""The participant's form page in a real browser: a link opens the SUS for a blinded
condition, the answers are scored, and the link closes."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.browser.conftest import SharedServer, reading_shared, shared_server
from tests.databases import AccountTemplates


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
           account_templates: AccountTemplates) -> Iterator[SharedServer]:
    """The app without a worker (the form page needs none), one for the module: each
    test makes its own study."""
    with shared_server(tmp_path_factory.mktemp("forms"), default_sets,
                       account_templates) as s:
        yield s


quiet_server, experimenter = reading_shared("quiet_server")


def test_participant_fills_in_the_sus_through_the_link(quiet_server: str, page: Any,
                                                       experimenter: dict[str, str]) -> None:
    api = httpx.Client(base_url=quiet_server)
    token = api.post("/api/auth/token", json=experimenter).json()["access_token"]
    api.headers["Authorization"] = f"Bearer {token}"
    sid = api.post("/api/studies", json={"name": "browser"}).json()["id"]
    pid = api.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    api.post(f"/api/participants/{pid}/conditions", json={"label": "A", "controller": "umc"})
    link = api.post(f"/api/participants/{pid}/links", json={
        "forms": [{"instrument_key": "sus", "condition_label": "A"}]}).json()

    page.goto(link["url"])
    page.wait_for_selector("form[data-form='0']")
    assert "setting A" in page.inner_text("form h2")
    assert "umc" not in page.content().lower()
    for item, value in zip([f"q{i}" for i in range(1, 11)],
                           [4, 1, 5, 2, 5, 1, 4, 2, 3, 1], strict=True):
        page.check(f"input[name='{item}'][value='{value}']")
    page.click("form[data-form='0'] button[type=submit]")
    page.wait_for_selector("text=this link is closed")
    responses = api.get(f"/api/participants/{pid}/responses").json()
    assert [(r["score"], r["controller"]) for r in responses] == [(85.0, "umc")]


def _sus(answers: list[int]) -> float:
    """The SUS formula (Brooke 1996), written out independently of the server's."""
    odd = sum(a - 1 for a in answers[0::2])
    even = sum(5 - a for a in answers[1::2])
    return (odd + even) * 2.5


def test_experimenter_makes_a_link_and_sees_the_sus_score_in_the_console(
        quiet_server: str, page: Any, experimenter: dict[str, str]) -> None:
    api = httpx.Client(base_url=quiet_server)
    token = api.post("/api/auth/token", json=experimenter).json()["access_token"]
    api.headers["Authorization"] = f"Bearer {token}"
    sid = api.post("/api/studies", json={"name": "forms"}).json()["id"]
    pid = api.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    session = api.post(f"/api/participants/{pid}/sessions",
                       json={"kind": "evaluation", "precompression_pct": 25}).json()
    trials = api.post(f"/api/sessions/{session['id']}/trials/plan",
                      json={"tasks": ["squat-sequence"], "include_eumc": False}).json()
    key = {c["label"]: c["controller"]
           for c in api.get(f"/api/participants/{pid}/conditions").json()}
    assert sorted(key.values()) == ["pec", "umc"] and len(trials) == 2
    label = next(k for k, v in key.items() if v == "pec")

    path = f"/console/sessions/{session['id']}"
    page.goto(f"{quiet_server}{path}")
    page.wait_for_url(f"**/login?next={path}")
    page.fill("#username", experimenter["username"])
    page.fill("#password", experimenter["password"])
    page.click("#submit")
    page.wait_for_url(f"{quiet_server}{path}")
    # Every section above the questionnaires has loaded (trials, utilities), so none
    # grows and moves the checkboxes between Playwright's aim and its click.
    page.wait_for_function("window.exostudySession && window.exostudySession.ready")
    page.wait_for_selector(f"#link-choices tr[data-condition='{label}'] input[value^='sus|']")
    # Only the SUS for the PEC's condition, and no preference question.
    for box in page.query_selector_all("#link-choices input[type=checkbox]"):
        box.uncheck()
    page.check(f"#link-choices input[value^='sus|'][value$='|{label}']")
    page.uncheck("#link-preference")
    page.click("#link-create")
    page.wait_for_selector("#link-out:not([hidden])")
    url = page.get_attribute("#link-url", "href")
    assert url and "/forms/" in url

    answers = [5, 2, 4, 1, 4, 2, 5, 1, 4, 2]
    tablet = page.context.browser.new_context().new_page()  # the participant: no login
    tablet.goto(url)
    tablet.wait_for_selector("form[data-form='0']")
    assert "pec" not in tablet.content().lower()
    for i, value in enumerate(answers, start=1):
        tablet.check(f"input[name='q{i}'][value='{value}']")
    tablet.click("form[data-form='0'] button[type=submit]")
    tablet.wait_for_selector("text=this link is closed")
    tablet.context.close()

    row = page.wait_for_selector("#responses tr[data-instrument=sus]", timeout=15000)
    cells = row.query_selector_all("td")
    assert [c.inner_text() for c in cells[1:4]] == [label, "PEC", f"{_sus(answers):.1f}"]
    assert _sus(answers) == 85.0

    # The participant's view on the study page shows the same score.
    page.goto(f"{quiet_server}/console/studies/{sid}")
    page.click("#participants tr[data-participant=P1] button.open")
    row = page.wait_for_selector("#participant-responses tr[data-instrument=sus]")
    cells = row.query_selector_all("td")
    assert [c.inner_text() for c in cells[1:4]] == [label, "PEC", f"{_sus(answers):.1f}"]
    assert page.locator("#participant-responses tbody tr").count() == 1


def test_the_form_on_a_tablet_shows_anchors_progress_big_targets_and_keeps_answers(
        quiet_server: str, page: Any, experimenter: dict[str, str]) -> None:
    api = httpx.Client(base_url=quiet_server)
    token = api.post("/api/auth/token", json=experimenter).json()["access_token"]
    api.headers["Authorization"] = f"Bearer {token}"
    sid = api.post("/api/studies", json={"name": "tablet"}).json()["id"]
    pid = api.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    for label, ctrl in (("A", "umc"), ("B", "pec")):
        api.post(f"/api/participants/{pid}/conditions", json={"label": label, "controller": ctrl})
    link = api.post(f"/api/participants/{pid}/links", json={
        "forms": [{"instrument_key": "sus", "condition_label": "A"}],
        "preference": True}).json()

    page.set_viewport_size({"width": 768, "height": 1024})  # a 10-inch tablet, portrait
    page.goto(link["url"])
    page.wait_for_selector("form[data-form='0']")
    assert page.inner_text("#form-progress") == "Form 1 of 2"
    # The SUS's anchors, where the published form has them: over 1 and over 5.
    q1 = page.locator("fieldset[data-item='q1'] label.choice")
    assert q1.count() == 5
    assert q1.nth(0).inner_text().startswith("Strongly disagree")
    assert q1.nth(4).inner_text().startswith("Strongly agree")
    assert [q1.nth(i).locator(".anchor").count() for i in range(5)] == [1, 0, 0, 0, 1]
    anchor_box = q1.nth(0).locator(".anchor").bounding_box()
    radio_box = q1.nth(0).locator("input").bounding_box()
    assert anchor_box["y"] + anchor_box["height"] <= radio_box["y"] + 1
    # Every choice is a touch target of at least 44 x 44 CSS pixels (WCAG 2.5.5).
    for box in page.locator("label.choice").evaluate_all(
            "els => els.map(e => e.getBoundingClientRect()).map(r => [r.width, r.height])"):
        assert box[0] >= 44 and box[1] >= 44, box
    assert page.evaluate("document.documentElement.scrollWidth") <= 768  # no sideways scroll

    # Half the answers, a reload, and they are still there.
    answers = [4, 1, 5, 2, 5, 1, 4, 2, 3, 1]
    for i, value in enumerate(answers[:5], start=1):
        page.locator(f"fieldset[data-item='q{i}'] label.choice").nth(value - 1).click()
    page.reload()
    page.wait_for_selector("form[data-form='0']")
    for i, value in enumerate(answers[:5], start=1):
        assert page.is_checked(f"input[name='q{i}'][value='{value}']")
    for i, value in enumerate(answers[5:], start=6):
        page.locator(f"fieldset[data-item='q{i}'] label.choice").nth(value - 1).click()
    page.click("form[data-form='0'] button[type=submit]")
    page.wait_for_selector("#preference")
    assert page.inner_text("#form-progress") == "Form 2 of 2"
    page.locator("#preference label.choice", has_text="setting B").click()
    page.click("#preference button[type=submit]")
    page.wait_for_selector("text=this link is closed")
    responses = api.get(f"/api/participants/{pid}/responses").json()
    assert [r["score"] for r in responses] == [_sus(answers)] == [85.0]
    assert [p["choice"] for p in api.get(f"/api/participants/{pid}/preferences").json()] == ["B"]


#: An anchor label at the length limit: words a tablet cannot fit whole, one of them a
#: single unbroken 60-letter word.
LONG_ANCHOR = ("Extraordinarily " + "a" * 60 + " " + "unbearably strenuous beyond " * 5)[:200]


@pytest.mark.parametrize("hi", [10, 100], ids=["11-points", "101-points"])
def test_long_anchor_labels_and_long_scales_stay_inside_the_form(
        quiet_server: str, page: Any, experimenter: dict[str, str], hi: int) -> None:
    api = httpx.Client(base_url=quiet_server)
    token = api.post("/api/auth/token", json=experimenter).json()["access_token"]
    api.headers["Authorization"] = f"Bearer {token}"
    sid = api.post("/api/studies", json={"name": f"anchors {hi}"}).json()["id"]
    r = api.post(f"/api/studies/{sid}/instruments", json={
        "key": "strain", "version": "1", "title": "Strain",
        "items": [{"id": "q1", "text": "How strenuous was it?"},
                  {"id": "q2", "text": "How tiring was it?"}],
        "scale": {"min": 0, "max": hi, "labels": [
            {"value": 0, "label": "not at all " + "x" * 50},
            {"value": hi, "label": LONG_ANCHOR}]},
        "aggregation": {"method": "sum"}, "score_range": {"min": 0, "max": 2 * hi},
        "provenance": {"wording": "study"}})
    assert r.status_code == 201, r.text
    pid = api.post(f"/api/studies/{sid}/participants", json={"code": "P1"}).json()["id"]
    link = api.post(f"/api/participants/{pid}/links", json={
        "forms": [{"instrument_key": "strain"}]}).json()

    page.set_viewport_size({"width": 768, "height": 1024})
    page.goto(link["url"])
    page.wait_for_selector("form[data-form='0']")
    # Every choice and anchor inside its item's box, no anchor wider than its choice.
    outside = page.evaluate("""() => {
        const bad = [];
        for (const item of document.querySelectorAll("fieldset.item")) {
            const box = item.getBoundingClientRect();
            for (const el of item.querySelectorAll("label.choice, .anchor")) {
                const r = el.getBoundingClientRect();
                if (r.left < box.left - 1 || r.right > box.right + 1
                        || el.scrollWidth > el.clientWidth + 1) {
                    bad.push([el.className, Math.round(r.left), Math.round(r.right),
                              Math.round(box.right), el.scrollWidth, el.clientWidth]);
                }
            }
        }
        return bad;
    }""")
    assert outside == []
    assert page.evaluate("document.documentElement.scrollWidth") <= 768
    assert page.locator("fieldset[data-item='q1'] label.choice").count() == hi + 1
