"""The Lab Streaming Layer's cost and speed: the default `make run` set-up (simulated
exoskeleton process on UDP, worker, server, SQLite) run twice in the same run, with the
LSL outlets off (baseline) and on (with an inlet in this process pulling the tick stream,
so the outlet really sends), each for `--seconds`:

- worker overruns and period jitter p99 in each phase (target: no overrun added by LSL);
- the latency of an event marker from the console's request to the marker's arrival on
  an LSL inlet (`--markers` markers, one every 0.2 s; target: under 50 ms), and how far
  the marker's LSL stamp is from its tick's read time (it is the tick's own time).

    .venv/bin/python bench/bench_lab.py [--seconds 30] [--markers 50]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import httpx  # noqa: E402
import pylsl  # noqa: E402

from tests.login import PASSWORD, USERNAME, create_experimenter  # noqa: E402
from tests.polling import free_tcp_port, free_udp_port, wait_for  # noqa: E402


def _pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(q * (len(s) - 1)))]


def phase(lsl: bool, seconds: float, markers: int, folder: Path) -> dict[str, Any]:
    """One server lifetime; returns its figures."""
    db = folder / f"lab-{int(lsl)}-{uuid.uuid4().hex[:6]}.db"
    url = f"sqlite:///{db}"
    create_experimenter(url)
    name = f"ExoStudyBench-{uuid.uuid4().hex[:6]}"
    port = free_tcp_port()
    # The server is its own process (`exostudy serve`), as for a lab: the console's
    # requests and this process's inlets do not share its interpreter. The default
    # model and utility sets (var/, built if missing) are used.
    env = {**os.environ, "EXOSTUDY_DATABASE_URL": url, "EXOSTUDY_DEMO": "false",
           "EXOSTUDY_LSL_ENABLED": str(lsl).lower(), "EXOSTUDY_LSL_NAME": name,
           "EXOSTUDY_DEVICE_KIND": "udp",
           "EXOSTUDY_DEVICE_ADDRESS": f"127.0.0.1:{free_udp_port()}"}
    server = subprocess.Popen([sys.executable, "-m", "backend.cli", "serve", "--port",
                               str(port), "--log-level", "warning"], cwd=ROOT, env=env)
    base = f"http://127.0.0.1:{port}"
    out: dict[str, Any] = {"lsl": lsl}
    try:

        def answers() -> bool:
            if server.poll() is not None:
                raise SystemExit("the server exited")
            try:
                return httpx.get(f"{base}/api/health", timeout=1.0).is_success
            except httpx.TransportError:
                return False

        wait_for(answers, 120, "the server", poll=0.2)
        api = httpx.Client(base_url=base, timeout=30)
        token = api.post("/api/auth/token", json={"username": USERNAME, "password": PASSWORD}
                         ).json()["access_token"]
        api.headers["Authorization"] = f"Bearer {token}"
        wait_for(lambda: api.get("/api/health").json()["worker"]["ticks"] >= 100, 120,
                 "the worker's first ticks", poll=0.2)
        study = api.post("/api/studies", json={"name": "bench"}).json()["id"]
        pid = api.post(f"/api/studies/{study}/participants", json={"code": "B01"}).json()["id"]
        sid = api.post(f"/api/participants/{pid}/sessions",
                       json={"kind": "evaluation", "precompression_pct": 25}).json()["id"]
        stop = threading.Event()
        pulled = [0]
        arrivals: dict[str, tuple[float, float]] = {}
        if lsl:
            tick_inlet = pylsl.StreamInlet(pylsl.resolve_byprop("name", name, 1, 10)[0])
            marker_inlet = pylsl.StreamInlet(
                pylsl.resolve_byprop("name", f"{name}-Markers", 1, 10)[0])
            tick_inlet.open_stream(5)
            marker_inlet.open_stream(5)

            def pull_ticks() -> None:
                while not stop.is_set():
                    chunk, _ = tick_inlet.pull_chunk(timeout=0.2)
                    pulled[0] += len(chunk)

            def pull_markers() -> None:
                while not stop.is_set():
                    sample, ts = marker_inlet.pull_sample(timeout=0.2)
                    if sample is not None:
                        arrivals[json.loads(sample[0]).get("note", "")] = (time.perf_counter(),
                                                                           ts)

            threading.Thread(target=pull_ticks, daemon=True).start()
            threading.Thread(target=pull_markers, daemon=True).start()
        h0 = api.get("/api/health").json()["worker"]
        t0 = time.monotonic()
        sent: dict[str, tuple[float, float]] = {}
        plain: list[float] = []
        for k in range(markers if lsl else 0):
            key = f"m{k}"
            before = time.perf_counter()
            m = api.post(f"/api/sessions/{sid}/markers", json={"label": "bench", "note": key})
            sent[key] = (before, m.json()["lsl_time"])
            time.sleep(0.1)
            # Baseline of the same moment: an authenticated request that does nothing.
            before = time.perf_counter()
            api.get(f"/api/sessions/{sid}/marker-labels")
            plain.append((time.perf_counter() - before) * 1000)
            time.sleep(0.1)
        time.sleep(max(0.0, seconds - (time.monotonic() - t0)))
        h1 = api.get("/api/health").json()["worker"]
        time.sleep(0.5)
        stop.set()
        out["overruns"] = h1["overruns"] - h0["overruns"]
        out["ticks"] = h1["ticks"] - h0["ticks"]
        out["jitter_p99_ms"] = h1["jitter_p99_ms"]
        out["pulled"] = pulled[0]
        lat = [(arrivals[k][0] - sent[k][0]) * 1000 for k in sent if k in arrivals]
        stamp = [abs(arrivals[k][1] - sent[k][1]) * 1000 for k in sent if k in arrivals]
        out["markers_sent"], out["markers_received"] = len(sent), len(lat)
        if lat:
            out["marker_ms"] = (statistics.median(lat), _pct(lat, 0.95), max(lat))
            out["plain_ms"] = (statistics.median(plain), _pct(plain, 0.95), max(plain))
            out["stamp_vs_stored_ms"] = max(stamp)
    finally:
        server.send_signal(signal.SIGINT)  # uvicorn's graceful stop: worker, device
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            server.kill()
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seconds", type=float, default=30.0)
    p.add_argument("--markers", type=int, default=50)
    p.add_argument("--rounds", type=int, default=2,
                   help="off/on pairs, alternating (the machine's load drifts)")
    args = p.parse_args()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        os.environ.setdefault("LSLAPICFG", str(ROOT / "tests/backend/lab/lsl_api.cfg"))
        for _ in range(args.rounds):
            results.append(phase(False, args.seconds, 0, folder))
            results.append(phase(True, args.seconds, args.markers, folder))
    for r in results:
        print(f"LSL {'on ' if r['lsl'] else 'off'}: {r['ticks']} ticks, overruns "
              f"{r['overruns']}, jitter p99 {r['jitter_p99_ms']:.2f} ms"
              + (f", inlet pulled {r['pulled']} samples" if r["lsl"] else ""))
        if "marker_ms" in r:
            p50, p95, mx = r["marker_ms"]
            b50, b95, bmx = r["plain_ms"]
            print(f"  marker console->LSL inlet: {r['markers_received']}/{r['markers_sent']} "
                  f"received, p50 {p50:.1f} ms, p95 {p95:.1f} ms, max {mx:.1f} ms "
                  f"(a request doing nothing, same run: p50 {b50:.1f}, p95 {b95:.1f}, "
                  f"max {bmx:.1f} ms); LSL stamp vs stored lsl_time: max "
                  f"{r['stamp_vs_stored_ms']:.3f} ms")
    off = sum(r["overruns"] for r in results if not r["lsl"])
    on = sum(r["overruns"] for r in results if r["lsl"])
    print(f"overruns: LSL off {off}, LSL on {on} ({args.rounds} x {args.seconds:g} s each)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
