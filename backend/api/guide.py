"""The guide (the MkDocs site built from `docs/`) at /guide/, behind the login.

The files come from `backend.core.resources.guide_dir()`: the wheel's bundled copy, or
`site/` in a clone (`make run` builds it). The theme starts each page with a few inline
scripts (colour scheme, base URL); rather than allow inline scripts, each page is sent
with a Content-Security-Policy that names exactly those scripts by their SHA-256, so the
app's policy otherwise holds: nothing from another origin, nothing else inline.
"""

from __future__ import annotations

import base64
import hashlib
import re
from functools import lru_cache
from pathlib import Path

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import FileResponse, RedirectResponse, Response

from backend.api.deps import SESSION_COOKIE, login_from_token
from backend.api.web_surface import CSP
from backend.core import resources

router = APIRouter(include_in_schema=False)

_INLINE_SCRIPT = re.compile(rb"<script(?![^>]*\bsrc=)(?![^>]*application/json)[^>]*>(.*?)"
                            rb"</script>", re.S)


def page_csp(html: bytes) -> str:
    """The app's policy, plus the hash of each inline script of this page."""
    hashes = sorted({"'sha256-" + base64.b64encode(hashlib.sha256(m.group(1)).digest())
                     .decode() + "'" for m in _INLINE_SCRIPT.finditer(html)})
    if not hashes:
        return CSP
    return CSP.replace("script-src 'self'", "script-src 'self' " + " ".join(hashes), 1)


@lru_cache(maxsize=256)
def _html_csp(path: Path, mtime_ns: int) -> str:
    return page_csp(path.read_bytes())


#: Longest name of one file or folder, and of a whole path, that a page may have (the
#: usual file system limits; the built guide's longest path is under 100 characters).
MAX_NAME_BYTES = 255
MAX_PATH_BYTES = 1024


def _plausible(rel: str) -> bool:
    """Whether `rel` can name a file at all: no NUL or other control character (the
    operating system refuses NUL), no name or path longer than the file system allows
    (`ENAMETOOLONG`). Anything else is for the file system to find or not."""
    raw = rel.encode("utf-8", "surrogateescape")
    return (len(raw) <= MAX_PATH_BYTES and not any(ch < 0x20 or ch == 0x7F for ch in raw)
            and all(len(part) <= MAX_NAME_BYTES for part in raw.split(b"/")))


def _file(root: Path, rel: str) -> Path:
    """`rel` inside `root`, or 404: no way out of the guide's folder, and a name no file
    can have is a page that does not exist, not an error."""
    missing = HTTPException(404, f"no page {rel[:100]!r} in the guide")
    if not _plausible(rel):
        raise missing
    try:
        target = (root / (rel or "index.html")).resolve()
        if target.is_dir():
            target = target / "index.html"
        if not target.is_relative_to(root.resolve()) or not target.is_file():
            raise missing
    except (OSError, ValueError):  # whatever else the file system refuses to look up
        raise missing from None
    return target


@router.get("/guide")
def guide_root() -> Response:
    """The guide's first page."""
    return RedirectResponse("/guide/index.html")


@router.get("/guide/{rel:path}")
def guide(request: Request, rel: str) -> Response:
    """A page or asset of the guide; the login page first for a visitor without one."""
    if login_from_token(request.app.state.sessions, request.cookies.get(SESSION_COOKIE)) is None:
        return RedirectResponse(f"/login?next={request.url.path}", status_code=303)
    root = resources.guide_dir()
    if not root.is_dir():
        raise HTTPException(404, "the guide is not built: run `mkdocs build` in the clone "
                            "(`make run` does)")
    path = _file(root, rel)
    response = FileResponse(path)
    if path.suffix == ".html":
        csp = _html_csp(path, path.stat().st_mtime_ns)
        response.headers["content-security-policy"] = csp
    return response
