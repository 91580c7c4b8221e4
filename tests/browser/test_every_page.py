"""Every console page loads in a real browser without a failed request or a console
error: no 404 (the icon included), no script error, no CSP violation."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from backend.core.config import Settings
from tests.live_server import running_server


@pytest.fixture
def quiet_server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    """The app without a worker: the pages must load whether or not one runs."""
    with running_server(settings) as url:
        yield url


def _study(server: str, experimenter: dict[str, str]) -> tuple[int, int]:
    """A study with one participant and an evaluation session, for the pages with ids."""
    with httpx.Client(base_url=server, timeout=30) as api:
        token = api.post("/api/auth/token", json=experimenter).json()["access_token"]
        api.headers["Authorization"] = f"Bearer {token}"
        sid = api.post("/api/studies", json={"name": "every page"}).json()["id"]
        pid = api.post(f"/api/studies/{sid}/participants", json={"code": "P01"}).json()["id"]
        sess = api.post(f"/api/participants/{pid}/sessions",
                        json={"kind": "evaluation", "precompression_pct": 25}).json()["id"]
    return sid, sess


def test_every_page_loads_without_a_failed_request_or_console_error(
        quiet_server: str, browser: Any, experimenter: dict[str, str]) -> None:
    sid, sess = _study(quiet_server, experimenter)
    # The app's CSP enforced (the shared `page` fixture bypasses it).
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = context.new_page()
    problems: list[str] = []
    page.on("response", lambda r: problems.append(f"{r.status} {r.url}")
            if r.status >= 400 else None)
    page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}")
            if m.type == "error" else None)
    page.on("pageerror", lambda exc: problems.append(f"script: {exc}"))

    page.goto(f"{quiet_server}/login?next=/console")
    page.fill("#username", experimenter["username"])
    page.fill("#password", experimenter["password"])
    page.click("#submit")
    page.wait_for_url(f"{quiet_server}/console")
    pages = ["/live", "/console", f"/console/studies/{sid}", f"/console/studies/{sid}/results",
             f"/console/sessions/{sess}", "/console/cohorts", "/admin", "/docs"]
    participant = page.request.get(f"{quiet_server}/api/sessions/{sess}").json()["participant_id"]
    pages.insert(4, f"/console/participants/{participant}/progress")
    for path in pages:
        page.goto(f"{quiet_server}{path}")
        page.wait_for_load_state("networkidle")
        icon = page.evaluate("document.querySelector('link[rel=icon]')?.href "
                             "?? new URL('/favicon.ico', location.href).href")
        assert page.request.get(icon).status == 200, (path, icon)
        if path != "/docs":
            # The shared header: the brand and the navigation, the section marked.
            assert page.locator("header.bar .brand").inner_text() == "ExoStudy", path
            assert page.locator("header.bar nav a.active").count() == 1, path
    favicon = page.request.get(f"{quiet_server}/favicon.ico")
    assert favicon.status == 200 and favicon.headers["content-type"] == "image/svg+xml"
    context.close()
    assert problems == []
