"""The 3D view: viser's client through the app (behind the login, no internet), its
WebSocket relayed to viser, the scene following the live ticks."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.browser.conftest import SharedServer, reading_shared, shared_server
from tests.databases import AccountTemplates
from tests.polling import wait_for


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
           account_templates: AccountTemplates) -> Iterator[SharedServer]:
    """One real server and worker for both tests (one logs in, one must not be let in)."""
    with shared_server(tmp_path_factory.mktemp("viewer"), default_sets, account_templates,
                       start_worker=True) as s:
        yield s


server, experimenter = reading_shared()


def test_viewer_shows_the_scene_and_follows_the_ticks(logged_in: str, page: Any) -> None:
    server = logged_in
    # The scene is drawn in software (SwiftShader's WebGL), at a cost that grows with the
    # canvas: a smaller window shows the same scene for less CPU.
    page.set_viewport_size({"width": 640, "height": 480})
    page.goto(f"{server}/viewer/")
    page.wait_for_selector("canvas", timeout=20000)

    def status() -> Any:
        """The viewer's status, asked with the page's login by Playwright rather than by
        the page, whose thread is busy drawing the scene in software."""
        r = page.request.get(f"{server}/viewer/status")
        assert r.ok, r.status
        return r.json()

    first = wait_for(lambda: (s := status())["clients"] >= 1 and s, 20,
                     "the 3D view's client to connect", poll=0.1)
    assert first["running"] and first["port"] != int(server.rsplit(":", 1)[1])
    later = wait_for(lambda: (s := status())["updates"] > first["updates"] and s, 10,
                     "the scene to follow the ticks", poll=0.1)
    assert later["updates"] > first["updates"], "the scene does not follow the ticks"
    assert later["last_q_deg"] is not None


def test_viewer_needs_a_login(server: str, page: Any) -> None:
    page.goto(f"{server}/viewer/")
    page.wait_for_url("**/login?next=/viewer/")
