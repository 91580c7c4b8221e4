"""The 3D view: viser's client through the app (behind the login, no internet), its
WebSocket relayed to viser, the scene following the live ticks."""

from __future__ import annotations

from typing import Any


def test_viewer_shows_the_scene_and_follows_the_ticks(logged_in: str, page: Any) -> None:
    server = logged_in
    page.goto(f"{server}/viewer/")
    page.wait_for_selector("canvas", timeout=20000)

    def status() -> Any:
        return page.evaluate("fetch('/viewer/status').then(r => r.json())")

    page.wait_for_function(
        "fetch('/viewer/status').then(r => r.json()).then(s => s.clients >= 1)", timeout=20000)
    first = status()
    assert first["running"] and first["port"] != int(server.rsplit(":", 1)[1])
    page.wait_for_timeout(1500)
    later = status()
    assert later["updates"] > first["updates"], "the scene does not follow the ticks"
    assert later["last_q_deg"] is not None


def test_viewer_needs_a_login(server: str, page: Any) -> None:
    page.goto(f"{server}/viewer/")
    page.wait_for_url("**/login?next=/viewer/")
