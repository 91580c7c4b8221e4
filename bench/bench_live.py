"""The live path under load: the default `make run` set-up (simulated exoskeleton process
on UDP, worker, server, SQLite) with 0, 3 and 4 real Chromium consoles open.

Per phase: worker overruns and period jitter (the 0-console phase is the baseline of the
same run), ticks stored per second (100 Hz logging holds?), and per console the updates
per second and the latency from the worker reading a sample to the page receiving it
(p50/p95/p99; the device is on loopback, so this is within about a millisecond of the
device timestamp). Targets: p95 <= 50 ms and >= 30 updates/s with 4 consoles, no
overruns caused by the consoles or the database.

    .venv/bin/python bench/bench_live.py [--seconds 30]
"""

from __future__ import annotations

import argparse
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


def _free(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _health(base: str, cookies: dict[str, str]) -> dict[str, Any]:
    return httpx.get(f"{base}/api/health", cookies=cookies).json()  # type: ignore[no-any-return]


def _phase(base: str, cookies: dict[str, str], browser: Any, consoles: int,
           seconds: float) -> dict[str, Any]:
    pages = []
    for _ in range(consoles):
        ctx = browser.new_context()
        ctx.add_cookies([{"name": k, "value": v, "url": base} for k, v in cookies.items()])
        page = ctx.new_page()
        page.goto(f"{base}/live")
        page.wait_for_function("window.exostudyLive && exostudyLive.samples > 50", timeout=30000)
        page.evaluate("exostudyLive.latencies.length = 0")
        pages.append(page)
    h0 = _health(base, cookies)
    starts = [p.evaluate("({m: exostudyLive.messages, t: performance.now()})") for p in pages]
    time.sleep(seconds)
    h1 = _health(base, cookies)
    out: dict[str, Any] = {
        "consoles": consoles,
        "overruns": h1["worker"]["overruns"] - h0["worker"]["overruns"],
        "jitter_p99_ms": h1["worker"]["jitter_p99_ms"],
        "stored_per_s": (h1["database"]["ticks_written"] - h0["database"]["ticks_written"])
        / seconds,
        "worker_per_s": (h1["worker"]["ticks"] - h0["worker"]["ticks"]) / seconds,
    }
    rates, lat = [], []
    for p, s in zip(pages, starts, strict=True):
        e = p.evaluate("({m: exostudyLive.messages, t: performance.now(), "
                       "l: exostudyLive.latencies.slice()})")
        rates.append((e["m"] - s["m"]) / ((e["t"] - s["t"]) / 1000))
        lat += e["l"]
        p.context.close()
    if pages:
        lat.sort()
        q = statistics.quantiles(lat, n=100)
        out.update(updates_per_s_min=min(rates), latency_p50_ms=q[49], latency_p95_ms=q[94],
                   latency_p99_ms=q[98])
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--stream-rate", type=float, default=None,
                    help="messages per second per console (default: the server's setting)")
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
                            demo=False, _env_file=None)
        if args.stream_rate is not None:
            settings = settings.model_copy(update={"stream_rate": args.stream_rate})
        server = uvicorn.Server(uvicorn.Config(create_app(settings), host="127.0.0.1", port=port,
                                               log_level="warning", ws="websockets-sansio"))
        threading.Thread(target=server.run, daemon=True).start()
        while not server.started:
            time.sleep(0.1)
        base = f"http://127.0.0.1:{port}"
        r = httpx.post(f"{base}/api/auth/login", json={"username": USERNAME, "password": PASSWORD})
        cookies = dict(r.cookies)
        while _health(base, cookies)["worker"]["ticks"] < 300:
            time.sleep(0.2)
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=[
                "--headless=new", "--no-sandbox", "--disable-gpu",
                "--disable-background-networking", "--disable-renderer-backgrounding",
                "--disable-background-timer-throttling"])
            results = [_phase(base, cookies, browser, n, args.seconds) for n in (0, 3, 4)]
            browser.close()
        server.should_exit = True
        time.sleep(2)
    print(f"{'consoles':>8} {'overruns':>8} {'jitter p99':>10} {'stored/s':>9} "
          f"{'updates/s (min)':>15} {'latency p50/p95/p99 ms':>24}")
    for r in results:
        lat = (f"{r['latency_p50_ms']:.1f}/{r['latency_p95_ms']:.1f}/{r['latency_p99_ms']:.1f}"
               if "latency_p95_ms" in r else "-")
        ups = f"{r['updates_per_s_min']:.1f}" if "updates_per_s_min" in r else "-"
        print(f"{r['consoles']:>8} {r['overruns']:>8} {r['jitter_p99_ms']:>8.2f}ms "
              f"{r['stored_per_s']:>9.1f} {ups:>15} {lat:>24}")
    four = results[-1]
    ok = four["latency_p95_ms"] <= 50 and four["updates_per_s_min"] >= 30 and all(
        r["overruns"] == 0 for r in results)
    print(f"targets (4 consoles: p95 <= 50 ms, >= 30 updates/s; no overruns): "
          f"{'PASS' if ok else 'FAIL'}")


if __name__ == "__main__":
    main()
