"""Logging in the way a person does: open a page, be sent to the login page, type the
credentials, land back on the page asked for. Every browser test that needs a login
goes through this one path, so a change to the login page is met in one place."""

from __future__ import annotations

from typing import Any


def log_in_through(page: Any, server: str, path: str, credentials: dict[str, str]) -> None:
    """Open `path` without a login; log in on the page it redirects to; wait to be back."""
    page.goto(f"{server}{path}")
    page.wait_for_url(f"**/login?next={path}")
    page.fill("#username", credentials["username"])
    page.fill("#password", credentials["password"])
    page.click("#submit")
    page.wait_for_url(f"{server}{path}")
