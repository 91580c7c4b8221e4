"""The experimenter's console pages: static HTML behind the login.

The pages themselves hold no data; their scripts read everything through the API, so
the login check here only decides between the page and the login page."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, Request
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, RedirectResponse, Response

from backend.api.deps import SESSION_COOKIE, login_from_token
from backend.api.params import MAX_ID

router = APIRouter(include_in_schema=False)

PageId = Annotated[int, PathParam(ge=1, le=MAX_ID)]


def _page(request: Request, name: str) -> Response:
    if login_from_token(request.app.state.sessions, request.cookies.get(SESSION_COOKIE)) is None:
        # Back to this very page after logging in; the path is ours, never another site.
        return RedirectResponse(f"/login?next={request.url.path}", status_code=303)
    static: Path = request.app.state.settings.frontend_dir / "static"
    return FileResponse(static / name)


@router.get("/admin")
def admin(request: Request) -> Response:
    """Accounts: one's password and logins; for an admin, every account."""
    return _page(request, "admin.html")


@router.get("/console")
def console(request: Request) -> Response:
    """Studies: list and create."""
    return _page(request, "console.html")


@router.get("/console/studies/{study_id}")
def study(request: Request, study_id: PageId) -> Response:
    """A study: participants and their sessions."""
    return _page(request, "study.html")


@router.get("/console/studies/{study_id}/results")
def results(request: Request, study_id: PageId) -> Response:
    """A study's results: tables, figures, trials, what-if replay, model evaluation."""
    return _page(request, "results.html")


@router.get("/console/cohorts")
def cohorts(request: Request) -> Response:
    """Virtual cohorts: run one, follow its progress, read its tables and power curves."""
    return _page(request, "cohorts.html")


@router.get("/console/sessions/{session_id}")
def session(request: Request, session_id: PageId) -> Response:
    """A session: the protocol step by step."""
    return _page(request, "session.html")
