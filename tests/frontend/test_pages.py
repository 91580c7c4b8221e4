"""The console's page shell: every page gets the same head and header from one place."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from backend.console_pages import NAVIGATION, render_page

PAGES = Path(__file__).resolve().parents[2] / "frontend" / "pages"


@pytest.mark.parametrize("path", sorted(PAGES.glob("*.html")), ids=lambda p: p.stem)
def test_every_page_renders_with_the_shared_head(path: Path) -> None:
    out = render_page(path.read_text(), path.name)
    assert out.startswith("<!doctype html>") and out.rstrip().endswith("</html>")
    assert out.count("<head>") == 1 and out.count('<header class="bar">') == 1
    assert '<link rel="icon" href="/static/favicon.svg"' in out
    assert out.count('<strong class="brand">ExoStudy</strong>') == 1
    title = re.search(r"<title>ExoStudy · ([^<]+)</title>", out)
    assert title is not None
    if path.stem != "login":
        assert '<script src="/static/guard.js"></script>' in out
        assert out.count(' class="active"') == 1
        nav = re.search(r'<nav class="nav">(.*?)</nav>', out)
        assert nav is not None
        assert re.findall(r'href="([^"]+)"', nav[1]) == [h for h, _ in NAVIGATION]
    else:
        assert "guard.js" not in out and "<nav" not in out


def test_navigation_marks_the_current_section() -> None:
    out = render_page('<!-- page title="x" nav="/console/cohorts" plots -->\n'
                      '<header class="bar"><span id="extra"></span></header><main></main>', "x")
    nav = re.search(r'<nav class="nav">(.*?)</nav>', out)
    assert nav is not None
    assert re.findall(r'href="([^"]+)"', nav[1]) == [h for h, _ in NAVIGATION]
    assert re.findall(r'<a href="([^"]+)" class="active">', nav[1]) == ["/console/cohorts"]
    assert "uPlot.min.css" in out
    assert '<span id="extra"></span>' in out


@pytest.mark.parametrize("text, wrong", [
    ('<header class="bar"></header>', "starts with"),
    ('<!-- page nav="/live" --><header class="bar"></header>', "needs title"),
    ('<!-- page title="x" colour="red" --><header class="bar"></header>', "needs title"),
    ('<!-- page title="x" nav="/nowhere" --><header class="bar"></header>', "not one of"),
    ('<!-- page title="x" --><main></main>', "header"),
])
def test_a_malformed_page_says_what_is_wrong(text: str, wrong: str) -> None:
    with pytest.raises(ValueError, match=wrong):
        render_page(text, "broken.html")


def test_pages_need_a_login_and_the_login_page_does_not(client: TestClient) -> None:
    assert client.get("/live").status_code == 200
    assert "ExoStudy · live" in client.get("/live").text
    assert "ExoStudy · session" in client.get("/console/sessions/3").text
    assert client.get("/console/studies/0/results").status_code == 422
    client.cookies.clear()
    r = client.get("/console", follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"] == "/login?next=/console"
    login = client.get("/login")
    assert login.status_code == 200 and "guard.js" not in login.text
