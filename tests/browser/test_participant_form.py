"""The participant's form page in a real browser: a link opens the SUS for a blinded
condition, the answers are scored, and the link closes."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from backend.core.config import Settings
from tests.live_server import running_server


@pytest.fixture
def quiet_server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    """The app without a worker: the form page needs none."""
    with running_server(settings) as url:
        yield url


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
