"""The guide at /guide/: behind the login, confined to its folder, and each page's inline
scripts allowed by hash rather than by 'unsafe-inline'."""

from __future__ import annotations

import base64
import hashlib
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from backend.api import guide
from backend.api.web_surface import CSP
from backend.core import resources
from tests.databases import AccountTemplates
from tests.module_client import logged_in_client

PAGE = (b'<html><head><script>var a=1;</script><script src="x.js"></script>'
        b'<script id="__config" type="application/json">{"b": 2}</script></head>'
        b"<body><script>\nvar c=3;\n</script></body></html>")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A small built guide in place of the real one, for the module (no test changes it)."""
    folder = tmp_path_factory.mktemp("guide")
    root = folder / "site"
    (root / "assets").mkdir(parents=True)
    (root / "index.html").write_bytes(PAGE)
    (root / "assets" / "app.js").write_text("console.log(1)")
    (folder / "secret.txt").write_text("outside the guide")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(resources, "guide_dir", lambda: root)
        yield root


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory, default_sets: tuple[Path, Path],
           account_templates: AccountTemplates) -> Iterator[TestClient]:
    """One logged-in app for the module: its tests only read the guide
    (`tests/module_client.py`)."""
    with logged_in_client(tmp_path_factory.mktemp("guide-db"), default_sets,
                          account_templates) as c:
        yield c


def _sha(script: bytes) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(script).digest()).decode() + "'"


def test_the_policy_names_exactly_the_inline_scripts() -> None:
    csp = guide.page_csp(PAGE)
    script_src = next(p for p in csp.split(";") if p.strip().startswith("script-src"))
    hashes = {w for w in script_src.split() if w.startswith("'sha256-")}
    assert hashes == {_sha(b"var a=1;"), _sha(b"\nvar c=3;\n")}
    assert "'unsafe-inline'" not in script_src
    assert csp.replace(" " + " ".join(sorted(hashes)), "") == CSP
    assert guide.page_csp(b"<p>no scripts</p>") == CSP


def test_the_guide_needs_a_login(client: TestClient, site: Path) -> None:
    anonymous = TestClient(client.app)
    r = anonymous.get("/guide/index.html", follow_redirects=False)
    assert r.status_code == 303
    assert r.headers["location"] == "/login?next=/guide/index.html"


def test_pages_and_assets_are_served_with_their_policy(client: TestClient, site: Path
                                                       ) -> None:
    r = client.get("/guide", follow_redirects=False)
    assert r.status_code == 307 and r.headers["location"] == "/guide/index.html"
    page = client.get("/guide/index.html")
    assert page.status_code == 200 and page.content == PAGE
    assert page.headers["content-security-policy"] == guide.page_csp(PAGE)
    asset = client.get("/guide/assets/app.js")
    assert asset.status_code == 200 and asset.text == "console.log(1)"
    assert asset.headers["content-security-policy"] == CSP
    assert client.get("/guide/").content == PAGE  # a folder opens its index


@pytest.mark.parametrize("path", ["/guide/../secret.txt", "/guide/%2e%2e/secret.txt",
                                  "/guide/assets/../../secret.txt", "/guide/missing.html"])
def test_nothing_outside_the_guide_is_served(client: TestClient, site: Path, path: str
                                             ) -> None:
    r = client.get(path, follow_redirects=False)
    assert r.status_code in (303, 404) and "outside the guide" not in r.text, path


@pytest.mark.parametrize("path", [
    "/guide/%00", "/guide/index.html%00.js", "/guide/assets/%00/app.js",
    "/guide/" + "a" * 300, "/guide/assets/" + "b" * 300 + ".js",
    "/guide/" + "/".join(["c" * 200] * 30), "/guide/%0aindex.html"],
    ids=["nul", "nul-in-name", "nul-folder", "300-characters", "300-in-folder",
         "6000-characters", "newline"])
def test_bad_names_are_a_404_not_a_500(client: TestClient, site: Path, path: str) -> None:
    r = TestClient(client.app, raise_server_exceptions=False).get(
        path, cookies=client.cookies, follow_redirects=False)
    assert r.status_code == 404, (r.status_code, r.text[:200])
