"""Participant link tokens are cut short in logs (issue 23: uvicorn's access log held
them in full, and a token is the link's only credential)."""

from __future__ import annotations

import logging

import pytest
from fastapi.testclient import TestClient

from backend.api import log_redaction

TOKEN = "Zq3xVb7-Kp1_aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa"


@pytest.mark.parametrize("path", [f"/api/participant-forms/{TOKEN}/responses",
                                  f"/forms/{TOKEN}", f"/api/participant-forms/{TOKEN}?x=1"])
def test_the_access_log_line_keeps_a_prefix_only(
        path: str, client: TestClient, caplog: pytest.LogCaptureFixture) -> None:
    # The app is built (so the filter is installed) as when uvicorn serves it.
    caplog.set_level(logging.INFO, logger="uvicorn.access")
    # uvicorn's own access log call (uvicorn/protocols/http/*_impl.py).
    logging.getLogger("uvicorn.access").info('%s - "%s %s HTTP/%s" %d', "127.0.0.1:5000",
                                             "GET", path, "1.1", 200)
    line = caplog.records[-1].getMessage()
    assert TOKEN not in line and f"{TOKEN[:6]}…" in line


def test_other_paths_are_left_alone() -> None:
    text = "/api/participants/12/links and /api/sessions/3/xdf"
    assert log_redaction.redact(text) == text
    assert log_redaction.redact(f"GET /forms/{TOKEN}") == f"GET /forms/{TOKEN[:6]}…"
