"""Playwright with Debian's Chromium (no browser download), a live server, and a guard
that fails any test whose page tried to reach beyond this machine."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import pytest

from backend.core.config import Settings
from tests.browser.login_page import log_in_through
from tests.databases import AccountTemplates
from tests.live_server import running_server

#: Debian's headless shell (package chromium-headless-shell, the same engine without the
#: browser's windows; `make test` installs it): `test_every_page.py` cost it 6.8 s of
#: CPU against 11.2 s for `chromium --headless=new` (measured with process accounting),
#: and `tests/browser` 113 s of CPU in all against 157 s. Where it is missing (a
#: browser test run outside `make test`), Debian's chromium in its new headless mode.
HEADLESS_SHELL = shutil.which("chromium-headless-shell")
CHROMIUM = HEADLESS_SHELL or shutil.which("chromium") or "/usr/bin/chromium"
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"
LOCAL_HOSTS = {"127.0.0.1", "localhost", "[::1]", "::1"}

pytestmark = pytest.mark.browser


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[Any]) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()  # type: ignore[attr-defined]
    setattr(item, f"rep_{report.when}", report)


@pytest.fixture(scope="package")
def browser() -> Iterator[Any]:
    """One Chromium for this folder's tests (a new context per test). Closed when the run
    leaves the folder: Playwright's sync API keeps an event loop running in the thread,
    and with `pytest -n 2` (`make test`) other folders' tests that call `asyncio.run`
    may follow in the same process."""
    if not os.path.exists(CHROMIUM):
        pytest.fail("Debian's chromium is missing: `make test` installs it "
                    "(apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(
            executable_path=CHROMIUM,
            args=[*([] if HEADLESS_SHELL else ["--headless=new"]),
                  "--no-sandbox", "--disable-gpu", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--disable-quic", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader"],
        )
        yield b
        b.close()


@pytest.fixture
def server(settings: Settings, experimenter: dict[str, str]) -> Iterator[str]:
    """The app with a real worker and the in-process simulated exoskeleton."""
    with running_server(settings.model_copy(update={"start_worker": True})) as url:
        yield url


@dataclass(frozen=True)
class SharedServer:
    """A server that all tests of one module use: its URL, its settings (the database
    among them) and the experimenter's login."""

    url: str
    settings: Settings
    login: dict[str, str]


@contextmanager
def shared_server(folder: Path, default_sets: tuple[Path, Path],
                  templates: AccountTemplates, **updates: Any) -> Iterator[SharedServer]:
    """One server (with `start_worker=True`, its worker too) on one new database holding
    the experimenter: the settings of the `settings` fixture with `updates`. For the
    modules whose tests each make their own study, session or account, so that none
    needs a database of its own: a server and worker started per test cost about 2.5 s
    of CPU and 5 s before the first tick (measured)."""
    from tests.databases import fresh_database, postgres_server
    from tests.login import PASSWORD, USERNAME, create_experimenter

    models, utilities = default_sets
    with fresh_database(folder) as url:
        login = ({"username": USERNAME, "password": PASSWORD}
                 if templates.fill(url, postgres_server()) else create_experimenter(url))
        settings = Settings(  # type: ignore[call-arg]
            database_url=url, start_worker=False, models_path=models, utilities_dir=utilities,
            device_kind="sim", demo=False, _env_file=None,
        ).model_copy(update=updates)
        with running_server(settings) as base:
            yield SharedServer(base, settings, login)


def reading_shared(url_fixture: str = "server") -> tuple[Any, Any]:
    """The fixtures a module whose tests share its `shared` server overrides with it:
    its URL (named `url_fixture`) and `experimenter`, the login it holds. Assign them to
    those names in the module: `server, experimenter = reading_shared()`."""

    @pytest.fixture(name=url_fixture)
    def url(shared: SharedServer) -> str:
        return shared.url

    @pytest.fixture(name="experimenter")
    def login(shared: SharedServer) -> dict[str, str]:
        return shared.login

    return url, login


@pytest.fixture
def page(browser: Any, request: pytest.FixtureRequest) -> Iterator[Any]:
    # bypass_csp: the app's Content-Security-Policy forbids evaluating strings, which
    # Playwright's polling `wait_for_function` does in the page; the CSP itself is
    # checked in a context without the bypass (tests/browser/test_access_pages.py).
    context = browser.new_context(viewport={"width": 1280, "height": 900}, bypass_csp=True)
    outside: list[str] = []

    def guard(route: Any) -> None:
        host = urlparse(route.request.url).hostname or ""
        if route.request.url.startswith(("data:", "blob:")) or host in LOCAL_HOSTS:
            route.continue_()
        else:
            outside.append(route.request.url)
            route.abort()

    context.route("**/*", guard)
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    yield pg
    failed = getattr(request.node, "rep_call", None)
    if failed is not None and failed.failed:
        ARTIFACTS.mkdir(exist_ok=True)
        pg.screenshot(path=str(ARTIFACTS / f"{request.node.name}.png"), full_page=True)
    context.close()
    assert not outside, f"the page tried to reach the internet: {outside}"
    assert not errors, f"JavaScript errors on the page: {errors}"


@pytest.fixture
def logged_in(server: str, page: Any, experimenter: dict[str, str]) -> str:
    """Log `page` in through the login page, as an experimenter would: opening the
    console without a login lands on the login page, which leads back to it."""
    log_in_through(page, server, "/live", experimenter)
    return server
