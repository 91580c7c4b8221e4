"""The cohorts page in Chromium: run a small cohort, watch the progress bar fill, read
the comparisons and see the power curves."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from backend.core.config import Settings
from tests.browser.login_page import log_in_through
from tests.live_server import running_server

pytestmark = [pytest.mark.browser, pytest.mark.slow]


@pytest.fixture
def plain_server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    """The app without a worker: a cohort needs none."""
    with running_server(settings) as url:
        yield url


def test_a_cohort_runs_from_the_page(plain_server: str, page: Any,
                                     experimenter: dict[str, str]) -> None:
    log_in_through(page, plain_server, "/console/cohorts", experimenter)
    page.wait_for_selector("body[data-ready='true']")
    assert page.is_visible("#cohorts-empty")

    page.fill("#cohort-participants", "3")
    page.uncheck("#cohort-eumc")
    page.click("#cohort-run")
    page.wait_for_selector("#cohort-progress:not([hidden])")
    page.wait_for_selector("body[data-shown]", timeout=300_000)
    assert page.eval_on_selector("#cohort-progress", "e => e.value") == 1
    # The message comes after the result is shown and the list reloaded.
    page.wait_for_selector("#cohort-msg.msg-ok")
    assert "ready" in page.text_content("#cohort-msg")

    rows = page.query_selector_all("#main-comparisons tbody tr")
    texts = [r.text_content() or "" for r in rows]
    assert any("support_asymmetry_nm" in t and "UMC − PEC" in t for t in texts), texts
    assert not any("E-UMC" in t for t in texts)  # not simulated, so not compared
    page.wait_for_function(
        "document.querySelector('#power-figure').complete && "
        "document.querySelector('#power-figure').naturalWidth > 0")
    assert page.query_selector_all("#summaries tbody tr")
    assert page.query_selector("#cohorts tbody tr[data-cohort]") is not None
