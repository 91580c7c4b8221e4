"""The experimenter's console pages: one page shell around each page's body, behind the login.

Every page shares its `<head>` (title, icon, style sheets, the CSRF guard) and the brand
and navigation of its header; only the body differs. The bodies live in
`frontend/pages/<name>.html` and start with a directive naming what the shell needs:

    <!-- page title="accounts" nav="/admin" plots -->

`title` follows "ExoStudy · "; `nav` is the navigation entry marked as current (none on
the login page); `plots` adds uPlot's style sheet; `public` serves the page without a
login and without the guard script (the login page). The page's own `<header
class="bar">` gets the brand and navigation in front of what it holds, and a place for
the name of who is logged in (filled in by `guard.js`) after it.

The pages hold no data; their scripts read everything through the API, so the login
check here only decides between the page and the login page.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, HTTPException, Request
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response

from backend.api.deps import SESSION_COOKIE, login_from_token
from backend.api.params import MAX_ID

router = APIRouter(include_in_schema=False)

PageId = Annotated[int, PathParam(ge=1, le=MAX_ID)]

#: The navigation of every console page: where it leads and what it says.
NAVIGATION: tuple[tuple[str, str], ...] = (
    ("/live", "Live"),
    ("/console", "Studies"),
    ("/console/cohorts", "Cohorts"),
    ("/console/replication", "Replication"),
    ("/viewer/", "3D view"),
    ("/hardware", "Hardware"),
    ("/admin", "Accounts"),
    ("/guide/index.html", "Guide"),
)
ICON = "/static/favicon.svg"

_DIRECTIVE = re.compile(r"\A\s*<!--\s*page\b(?P<attrs>.*?)-->\s*", re.S)
_ATTR = re.compile(r'(?P<key>[a-z]+)(?:="(?P<value>[^"]*)")?')
_BAR = '<header class="bar">'


@dataclass(frozen=True)
class PageShell:
    """What a page body's directive asks of the shell."""

    title: str
    nav: str | None = None
    plots: bool = False
    public: bool = False


def parse_directive(text: str, name: str) -> tuple[PageShell, str]:
    """The shell a page body asks for and the body after its directive."""
    m = _DIRECTIVE.match(text)
    if m is None:
        raise ValueError(f"{name}: a page body starts with <!-- page title=\"...\" -->")
    attrs = {a["key"]: a["value"] for a in _ATTR.finditer(m["attrs"])}
    unknown = set(attrs) - {"title", "nav", "plots", "public"}
    if unknown or not attrs.get("title"):
        raise ValueError(f"{name}: page directive needs title= and knows only nav=, plots, "
                         f"public; got {sorted(attrs)}")
    nav = attrs.get("nav")
    if nav is not None and nav not in dict(NAVIGATION):
        raise ValueError(f"{name}: nav={nav!r} is not one of {[h for h, _ in NAVIGATION]}")
    shell = PageShell(title=attrs["title"], nav=nav, plots="plots" in attrs,
                      public="public" in attrs)
    return shell, text[m.end():]


def render_page(text: str, name: str) -> str:
    """A page body wrapped in the shared shell: the complete HTML document."""
    shell, body = parse_directive(text, name)
    head = [
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>ExoStudy · {html.escape(shell.title)}</title>",
        f'<link rel="icon" href="{ICON}" type="image/svg+xml">',
    ]
    if shell.plots:
        head.append('<link rel="stylesheet" href="/vendor/uplot/uPlot.min.css">')
    head.append('<link rel="stylesheet" href="/static/style.css">')
    if not shell.public:
        head.append('<script src="/static/guard.js"></script>')
    bar = '<strong class="brand">ExoStudy</strong>'
    if not shell.public:
        active = ' class="active"'
        links = "".join(f'<a href="{href}"{active if href == shell.nav else ""}>{label}</a>'
                        for href, label in NAVIGATION)
        bar += f'<nav class="nav">{links}</nav>'
    if _BAR not in body:
        raise ValueError(f"{name}: a page body has a {_BAR} for the brand and navigation")
    body = body.replace(_BAR, _BAR + bar, 1)
    if not shell.public:  # who is logged in: guard.js fills it in
        end = body.index("</header>")
        body = body[:end] + '<span class="muted small" id="who"></span>' + body[end:]
    heads = "\n  ".join(head)
    return (f'<!doctype html>\n<html lang="en">\n<head>\n  {heads}\n</head>\n<body>\n'
            f"{body.rstrip()}\n</body>\n</html>\n")


def _pages_dir(request: Request) -> Path:
    return Path(request.app.state.settings.frontend_dir) / "pages"


def _html(request: Request, name: str) -> Response:
    return HTMLResponse(render_page((_pages_dir(request) / name).read_text(), name))


def _page(request: Request, name: str) -> Response:
    if login_from_token(request.app.state.sessions, request.cookies.get(SESSION_COOKIE)) is None:
        # Back to this very page after logging in; the path is ours, never another site.
        return RedirectResponse(f"/login?next={request.url.path}", status_code=303)
    return _html(request, name)


@router.get("/favicon.ico")
def favicon(request: Request) -> Response:
    """The icon, for clients that ask for it by the conventional name (the viewer, the
    API docs) rather than by the pages' `<link rel="icon">`."""
    path = Path(request.app.state.settings.frontend_dir) / "static" / "favicon.svg"
    if not path.is_file():
        raise HTTPException(404, "no icon installed")
    return FileResponse(path, media_type="image/svg+xml")


@router.get("/login")
def login(request: Request) -> Response:
    """The login page (no login needed, of course)."""
    return _html(request, "login.html")


#: Every page behind the login: its path (`{id}`: a positive id), body file, and content.
PAGES: tuple[tuple[str, str, str], ...] = (
    ("/live", "live.html",
     "The live stream: plots, state strip, worker and device health; a trial's replay."),
    ("/admin", "admin.html", "Accounts: one's password and logins; for an admin, every account."),
    ("/console", "console.html", "Studies: list and create."),
    ("/console/studies/{id}", "study.html", "A study: participants and their sessions."),
    ("/console/studies/{id}/model-sets", "model_sets.html",
     "A study's model sets (population and personal, with provenance) and prior sets."),
    ("/console/studies/{id}/results", "results.html",
     "A study's results: tables, figures, trials, what-if replay, model evaluation."),
    ("/console/cohorts", "cohorts.html",
     "Virtual cohorts: run one, follow its progress, read its tables and power curves."),
    ("/console/replication", "replication.html",
     "The paper replicated claim by claim: the newest report, or start one."),
    ("/console/sessions/{id}", "session.html", "A session: the protocol step by step."),
    ("/console/participants/{id}/progress", "wearer.html",
     "A wearer's long use: start and stop the controller, mark events, and the learning "
     "curves over sessions."),
    ("/hardware", "hardware.html",
     "Hardware bring-up: encoder zero, directions, offset, pulse, watchdog, link, profile."),
)


def _add_page(path: str, name: str, summary: str) -> None:
    def page(request: Request) -> Response:
        return _page(request, name)

    def page_with_id(request: Request, id: PageId) -> Response:
        return _page(request, name)

    router.add_api_route(path, page_with_id if "{id}" in path else page, methods=["GET"],
                         summary=summary)


for _path, _name, _summary in PAGES:
    _add_page(_path, _name, _summary)
