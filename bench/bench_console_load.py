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
import socket
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import httpx  # noqa: E402
import uvicorn  # noqa: E402

from backend.core.config import Settings  # noqa: E402
from backend.main import create_app  # noqa: E402
from tests.login import PASSWORD, USERNAME, create_experimenter  # noqa: E402

NAV = "JSON.stringify(performance.getEntriesByType('navigation')[0])"


def _free(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _open(browser: Any, base: str, cookies: dict[str, str], path: str,
          ready: str, mark: str | None) -> dict[str, float]:
    """One cold opening of `path`; milliseconds from navigation start.

    `ready` is polled; the time is the page's own performance mark `mark` when given
    (exact), else the moment the poll saw `ready` (up to a frame late).
    """
    import json

    ctx = browser.new_context()
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

    with tempfile.TemporaryDirectory() as d:
        url = f"sqlite:///{d}/bench.db"
        create_experimenter(url)
        port = _free(socket.SOCK_STREAM)
        settings = Settings(database_url=url, port=port, device_kind="udp",  # type: ignore[call-arg]
                            device_spawn_simulator=True,
                            device_address=f"127.0.0.1:{_free(socket.SOCK_DGRAM)}",
                            models_path=Path(d) / "models.json", utilities_dir=Path(d),
                            demo=True, _env_file=None)
        server = uvicorn.Server(uvicorn.Config(create_app(settings), host="127.0.0.1", port=port,
                                               log_level="warning", ws="websockets-sansio"))
        threading.Thread(target=server.run, daemon=True).start()
        while not server.started:
            time.sleep(0.1)
        base = f"http://127.0.0.1:{port}"
        cookies = dict(httpx.post(f"{base}/api/auth/login",
                                  json={"username": USERNAME, "password": PASSWORD}).cookies)
        while httpx.get(f"{base}/api/health", cookies=cookies).json()["worker"]["ticks"] < 300:
            time.sleep(0.2)
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=[
                "--headless=new", "--no-sandbox", "--disable-gpu",
                "--disable-background-networking"])
            cases: dict[str, tuple[str, str, str | None]] = {
                "baseline (static file)": ("/static/style.css",
                                           "document.readyState !== 'loading'", None),
                "/console (studies)": ("/console", "document.body.dataset.ready === 'true'",
                                       "exostudy-ready"),
                "/live (first sample drawn)": ("/live", "window.exostudyLive && "
                                               "exostudyLive.firstDrawMs != null",
                                               "exostudy-first-draw"),
            }
            for path, ready, mark in cases.values():  # warm-up: server and browser, not pages
                _open(browser, base, cookies, path, ready, mark)
            load0 = os.getloadavg()[0]
            results = {name: [_open(browser, base, cookies, path, ready, mark)
                              for _ in range(args.runs)]
                       for name, (path, ready, mark) in cases.items()}
            load1 = os.getloadavg()[0]
            browser.close()
        server.should_exit = True
        time.sleep(2)
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
