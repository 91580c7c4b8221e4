"""The live path under load: the default `make run` set-up (simulated exoskeleton process
on UDP, worker, server, SQLite) with 0, 3 and 4 real Chromium consoles open.

Per phase: worker overruns and period jitter (the 0-console phase is the baseline of the
same run), ticks stored per second (100 Hz logging holds?), and per console the updates
(messages) per second, the plot redraws per second (each frame redraws every plot in
view, at most 30 frames per second), and the latency from the worker reading a sample to
the page's JavaScript having handled the message that carries it (p50/p95/p99; the
device is on loopback, so this is within about a millisecond of the device timestamp).
Targets: p95 <= 50 ms and >= 30 updates/s with 4 consoles, no overruns caused by the
consoles or the database.

Two more figures say where the time goes: "server->page", from the server queuing a
message to the page handling it (so latency minus this is the worker's and the server's
batching), and "to drawn", from the worker reading a sample to the end of the first
redraw of the plots that includes it (drawn on the canvas, before the compositor puts it
on screen).

The window is 1280x720 by default (the strip and the first plot in view; plots out of
view are not redrawn); `--viewport 1280x2100` puts all five plots in view.

    .venv/bin/python bench/bench_live.py [--seconds 30] [--viewport 1280x720]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import httpx

from bench.server_rig import launch_chromium, running_server


def _health(base: str, cookies: dict[str, str]) -> dict[str, Any]:
    return httpx.get(f"{base}/api/health", cookies=cookies).json()


PROBE = "({m: exostudyLive.messages, d: exostudyLive.draws, t: performance.now()})"
# (transits and drawLatencies are missing in pages older than these figures: "-")
RESET = ("for (const k of ['latencies', 'transits', 'drawLatencies']) "
         "if (exostudyLive[k]) exostudyLive[k].length = 0")
COLLECT = ("({m: exostudyLive.messages, d: exostudyLive.draws, t: performance.now(), "
           "l: exostudyLive.latencies.slice(), s: (exostudyLive.transits || []).slice(), "
           "w: (exostudyLive.drawLatencies || []).slice()})")


def _pct(values: list[float]) -> list[float]:
    if len(values) < 2:
        return [math.nan] * 99
    return statistics.quantiles(sorted(values), n=100)


def _phase(base: str, cookies: dict[str, str], browser: Any, consoles: int,
           seconds: float, viewport: dict[str, int]) -> dict[str, Any]:
    pages = []
    errors: list[str] = []
    for _ in range(consoles):
        ctx = browser.new_context(viewport=viewport)
        ctx.add_cookies([{"name": k, "value": v, "url": base} for k, v in cookies.items()])
        page = ctx.new_page()
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(f"{base}/live")
        page.wait_for_function("window.exostudyLive && exostudyLive.samples > 50", timeout=30000)
        pages.append(page)
    time.sleep(1.0)  # the last page's start-up is not part of the measurement
    for p in pages:
        p.evaluate(RESET)
    load0 = os.getloadavg()[0]
    h0 = _health(base, cookies)
    starts = [p.evaluate(PROBE) for p in pages]
    time.sleep(seconds)
    h1 = _health(base, cookies)
    if errors:
        raise SystemExit(f"page errors: {errors}")
    out: dict[str, Any] = {
        "consoles": consoles,
        "load": (load0, os.getloadavg()[0]),
        "overruns": h1["worker"]["overruns"] - h0["worker"]["overruns"],
        "jitter_p99_ms": h1["worker"]["jitter_p99_ms"],
        "stored_per_s": (h1["database"]["ticks_written"] - h0["database"]["ticks_written"])
        / seconds,
        "worker_per_s": (h1["worker"]["ticks"] - h0["worker"]["ticks"]) / seconds,
    }
    rates, draws, lat, transit, drawn = [], [], [], [], []
    for p, s in zip(pages, starts, strict=True):
        e = p.evaluate(COLLECT)
        dt = (e["t"] - s["t"]) / 1000
        rates.append((e["m"] - s["m"]) / dt)
        draws.append((e["d"] - s["d"]) / dt)
        lat += e["l"]
        transit += e["s"]
        drawn += e["w"]
        p.context.close()
    if pages:
        q, qs, qw = _pct(lat), _pct(transit), _pct(drawn)
        out.update(updates_per_s_min=min(rates), draws_per_s_min=min(draws),
                   latency_p50_ms=q[49], latency_p95_ms=q[94], latency_p99_ms=q[98],
                   transit_p50_ms=qs[49], transit_p95_ms=qs[94],
                   drawn_p50_ms=qw[49], drawn_p95_ms=qw[94])
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--stream-rate", type=float, default=None,
                    help="messages per second per console (default: the server's setting)")
    ap.add_argument("--viewport", default="1280x720", help="browser window, WIDTHxHEIGHT")
    args = ap.parse_args()
    width, height = (int(v) for v in args.viewport.split("x"))
    viewport = {"width": width, "height": height}
    from playwright.sync_api import sync_playwright

    with running_server(stream_rate=args.stream_rate) as srv, sync_playwright() as pw:
        settings = srv.settings
        browser = launch_chromium(pw)
        results = [_phase(srv.base, srv.cookies, browser, n, args.seconds, viewport)
                   for n in (0, 3, 4)]
        browser.close()
    print(f"viewport {args.viewport}, stream rate "
          f"{args.stream_rate if args.stream_rate is not None else settings.stream_rate:g}/s, "
          f"{args.seconds:g} s per phase; load average (1 min) at the start / end of each phase")
    print(f"{'consoles':>8} {'load':>9} {'overruns':>8} {'jitter p99':>10} {'stored/s':>8} "
          f"{'updates/s':>9} {'plot draws/s':>12} {'latency p50/p95/p99 ms':>22} "
          f"{'server->page p50/p95':>20} {'to drawn p50/p95':>16}")
    for row in results:
        load = f"{row['load'][0]:.1f}/{row['load'][1]:.1f}"
        if "latency_p95_ms" in row:
            lat = "/".join(f"{row[f'latency_p{k}_ms']:.1f}" for k in (50, 95, 99))
            ups = f"{row['updates_per_s_min']:.1f}"
            drw = f"{row['draws_per_s_min']:.1f}"
            tr = f"{row['transit_p50_ms']:.1f}/{row['transit_p95_ms']:.1f}"
            dn = f"{row['drawn_p50_ms']:.1f}/{row['drawn_p95_ms']:.1f}"
        else:
            lat = ups = drw = tr = dn = "-"
        print(f"{row['consoles']:>8} {load:>9} {row['overruns']:>8} {row['jitter_p99_ms']:>8.2f}ms "
              f"{row['stored_per_s']:>8.1f} {ups:>9} {drw:>12} {lat:>22} {tr:>20} {dn:>16}")
    four = results[-1]
    ok = four["latency_p95_ms"] <= 50 and four["updates_per_s_min"] >= 30 and all(
        r["overruns"] == 0 for r in results)
    print(f"targets (4 consoles: p95 <= 50 ms, >= 30 updates/s; no overruns): "
          f"{'PASS' if ok else 'FAIL'}")


if __name__ == "__main__":
    main()
