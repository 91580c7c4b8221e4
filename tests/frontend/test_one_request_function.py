"""Every request of the pages goes through api.js's one request function (`respond`),
which sets the CSRF header: no script calls `fetch` itself or replaces it."""

from __future__ import annotations

import re
from pathlib import Path

STATIC = Path(__file__).resolve().parents[2] / "frontend" / "static"
#: A call of fetch, XMLHttpRequest or sendBeacon, or an assignment over fetch.
RAW = re.compile(r"\bfetch\s*\(|\bfetch\s*=|XMLHttpRequest|sendBeacon")


def raw_requests(text: str) -> list[str]:
    """The lines of a script that request or patch without the one request function."""
    return [line.strip() for line in text.splitlines()
            if RAW.search(line) and not line.lstrip().startswith("//")]


def test_only_the_request_function_calls_fetch() -> None:
    found = {p.name: raw_requests(p.read_text(encoding="utf-8"))
             for p in sorted(STATIC.glob("*.js"))}
    assert found.pop("api.js") == ["return fetch(path, init);"]
    assert {name: lines for name, lines in found.items() if lines} == {}


def test_the_check_sees_a_raw_call_and_a_patch() -> None:
    assert raw_requests('const r = await fetch("/api/x");') != []
    assert raw_requests("window.fetch = (input, init) => original(input, init);") != []
    assert raw_requests("  // fetch(url) in a comment") == []
    assert raw_requests('const r = await respond("GET", url);') == []
