"""Access in a real browser: the login page follows only same-site `next` paths, every
page warns while the demo password is published, and the accounts page manages
accounts under the app's Content-Security-Policy (the CSRF token sent by api.js's one
request function)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from backend.db.engine import make_engine, make_session_factory
from backend.study import accounts
from tests.browser.conftest import SharedServer, reading_shared, shared_server
from tests.databases import AccountTemplates


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
           account_templates: AccountTemplates) -> Iterator[SharedServer]:
    """The app without a worker, with a demo account whose password is published, one
    for the module: only the accounts test changes the accounts (the others log in)."""
    with shared_server(tmp_path_factory.mktemp("access"), default_sets,
                       account_templates) as s:
        engine = make_engine(s.settings.database_url)
        with make_session_factory(engine)() as db:
            accounts.create_user(db, "demo", "exostudy-demo", "member", published=True)
            db.commit()
        engine.dispose()
        yield s


quiet_server, experimenter = reading_shared("quiet_server")


def _log_in(page: Any, server: str, experimenter: dict[str, str], next_path: str) -> None:
    page.goto(f"{server}/login?next={next_path}")
    page.fill("#username", experimenter["username"])
    page.fill("#password", experimenter["password"])
    page.click("#submit")


@pytest.mark.parametrize("next_path", ["/%5Cevil.example/pwn", "//evil.example/pwn",
                                       "https://evil.example/", "/%09/evil.example"])
def test_login_never_redirects_to_another_site(quiet_server: str, page: Any,
                                               experimenter: dict[str, str],
                                               next_path: str) -> None:
    _log_in(page, quiet_server, experimenter, next_path)
    page.wait_for_url(f"{quiet_server}/live")


def test_pages_warn_about_the_demo_password_and_the_accounts_page_works(
        quiet_server: str, browser: Any, experimenter: dict[str, str]) -> None:
    # A context that enforces the app's CSP (the shared `page` fixture bypasses it).
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = context.new_page()
    violations: list[str] = []
    page.on("console", lambda m: violations.append(m.text)
            if "Content Security Policy" in m.text else None)
    page.on("pageerror", lambda exc: violations.append(str(exc)))
    _log_in(page, quiet_server, experimenter, "/console")
    page.wait_for_url(f"{quiet_server}/console")
    banner = page.wait_for_selector("#published-password-warning")
    assert "demo" in banner.inner_text() and "published" in banner.inner_text()
    page.goto(f"{quiet_server}/admin")
    page.wait_for_selector("body[data-ready=true]")
    assert page.is_visible("#published-password-warning")
    page.fill("#user-name", "nadia")
    page.fill("#user-password", "passwordpassword")  # long enough, but common
    page.click("#user-create")
    page.wait_for_selector("#user-msg.msg-bad")
    assert "password" in page.inner_text("#user-msg")
    page.fill("#user-password", "nadia's own long passphrase")
    page.click("#user-create")
    page.wait_for_selector("#users tr[data-user=nadia]")
    page.click("#users tr[data-user=demo] button.toggle-active")
    page.wait_for_selector("#users tr[data-user=demo] >> text=disabled")
    page.reload()
    page.wait_for_selector("body[data-ready=true]")
    assert not page.is_visible("#published-password-warning")
    for path in ("/live", "/console", "/docs"):
        page.goto(f"{quiet_server}{path}")
        page.wait_for_load_state("networkidle")
    context.close()
    assert violations == []
