"""How fast the console opens: "the console's first page is usable within 1 second".

Starts the app as `make run` does (real server, simulated exoskeleton process on UDP,
worker, SQLite with the demo study), logs in, then in Debian's Chromium opens /console
in a fresh browser context each time (empty cache: a cold first visit) and measures, from
navigation start:

- usable: the study list is drawn and clickable: console.js sets `body[data-ready]` and
  the performance mark `exostudy-ready` once the studies are in the table;
- DOMContentLoaded and load (Navigation Timing);
- for /live: the first samples drawn on the plots (the mark `exostudy-first-draw`, set by
  live.js after the first redraw that holds data: the WebSocket is open and has
  delivered ticks).

The baseline of the same run is an empty static page (/static/style.css loaded as a
page), i.e. what the browser, the network stack and the server cost without our code.

    .venv/bin/python bench/bench_console_load.py [--runs 10]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.server_rig import launch_chromium, running_server

NAV = "JSON.stringify(performance.getEntriesByType('navigation')[0])"


def _open(browser: Any, base: str, cookies: dict[str, str], path: str,
          ready: str, mark: str | None) -> dict[str, float]:
    """One cold opening of `path`; milliseconds from navigation start.

    `ready` is polled; the time is the page's own performance mark `mark` when given
    (exact), else the moment the poll saw `ready` (up to a frame late).
    """
    import json

    # bypass_csp: polling `ready` evaluates a string in the page, which the app's CSP
    # forbids (as it should); the pages' own code runs the same either way.
    ctx = browser.new_context(bypass_csp=True)
    ctx.add_cookies([{"name": k, "value": v, "url": base} for k, v in cookies.items()])
    page = ctx.new_page()
    page.goto(f"{base}{path}", wait_until="commit")
    page.wait_for_function(ready, timeout=30000)
    usable = float(page.evaluate("performance.now()"))
    if mark is not None:
        usable = float(page.evaluate(
            f"performance.getEntriesByName({json.dumps(mark)})[0].startTime"))
    page.wait_for_load_state("load")
    nav = json.loads(page.evaluate(NAV))
    ctx.close()
    return {"usable": usable, "dcl": float(nav["domContentLoadedEventEnd"]),
            "load": float(nav["loadEventEnd"])}


def _row(name: str, runs: list[dict[str, float]]) -> str:
    def stat(k: str) -> str:
        xs = [r[k] for r in runs]
        return f"{statistics.median(xs):7.0f} {max(xs):7.0f}"

    return f"{name:<28} {stat('usable')}   {stat('dcl')}   {stat('load')}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=10)
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    cases: dict[str, tuple[str, str, str | None]] = {
        "baseline (static file)": ("/static/style.css",
                                   "document.readyState !== 'loading'", None),
        "/console (studies)": ("/console", "document.body?.dataset.ready === 'true'",
                               "exostudy-ready"),
        "/live (first sample drawn)": ("/live", "window.exostudyLive && "
                                       "exostudyLive.firstDrawMs != null",
                                       "exostudy-first-draw"),
    }
    with running_server(demo=True) as srv, sync_playwright() as pw:
        browser = launch_chromium(pw)
        for path, ready, mark in cases.values():  # warm-up: server and browser, not pages
            _open(browser, srv.base, srv.cookies, path, ready, mark)
        load0 = os.getloadavg()[0]
        results = {name: [_open(browser, srv.base, srv.cookies, path, ready, mark)
                          for _ in range(args.runs)]
                   for name, (path, ready, mark) in cases.items()}
        load1 = os.getloadavg()[0]
        browser.close()
    print(f"load average (1 min) {load0:.2f} before, {load1:.2f} after; {args.runs} cold "
          "openings each (new browser context, empty cache); ms from navigation start")
    print(f"{'page':<28} {'usable med/max':>15}   {'DOMContentLoaded':>15}   {'load':>15}")
    for name, runs in results.items():
        print(_row(name, runs))
    worst = max(r["usable"] for r in results["/console (studies)"])
    print(f"target (/console usable within 1000 ms, every opening): "
          f"{'PASS' if worst <= 1000 else 'FAIL'} (max {worst:.0f} ms)")


if __name__ == "__main__":
    main()
