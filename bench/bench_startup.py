"""`exostudy serve` start-up, quiet and beside two busy loops: when `/api/health` first
answers, when the application is ready (`/api/health` 200, pages and the API served) and
when the worker is ready (its control loop has ticked).

    .venv/bin/python bench/bench_startup.py [--repeats 1]

Each start is a fresh process on a fresh data folder (a new SQLite database: every
migration, the demo study), with the default model and utility sets copied in (a first
start on a new machine also fits them, once) and the device simulator spawned as
`make run` does. "Busy loops" are two `python -c 'while True: pass'` processes started
before the server and stopped after it. Baseline in the same run: a fixed pure-Python
loop (10 million additions) timed before each start. Target: `/api/health` answers
within 10 s beside two busy loops.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import httpx  # noqa: E402

from bench.record import load_average, record  # noqa: E402
from tests.polling import free_tcp_port, free_udp_port  # noqa: E402

EXOSTUDY = ROOT / ".venv" / "bin" / "exostudy"
LIMIT_S = 180.0
#: Seconds after the first tick at which the link's drop counters are read.
STALE_WINDOW_S = 5.0


def _reference_loop() -> float:
    t0 = time.perf_counter()
    total = 0
    for i in range(10_000_000):
        total += i
    return time.perf_counter() - t0


def _sets(folder: Path) -> None:
    """The default sets as a previous start left them (fitting them is a first-start
    cost, measured by bench_cohort's model-set line)."""
    (folder / "models").mkdir(parents=True)
    (folder / "utilities").mkdir()
    shutil.copy(ROOT / "var" / "models" / "sim-default.json", folder / "models")
    for f in (ROOT / "var" / "utilities").glob("utilities-sim-p25.json"):
        shutil.copy(f, folder / "utilities")


#: The start as it was before `backend/core/starting.py`: build the application (every
#: import), then listen; the baseline of the staged start.
PREVIOUS = ("import sys, uvicorn; from backend.core.config import Settings; "
            "from backend.main import create_app; s = Settings(port=int(sys.argv[1])); "
            "uvicorn.run(create_app(s), host=s.host, port=s.port, log_level='warning')")


def one_start(busy: int, previous: bool = False) -> dict[str, float]:
    """Times (s from the process start) of the first answer, the first 200 and the
    first tick; the status code of the first answer."""
    loops = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
             for _ in range(busy)]
    try:
        with tempfile.TemporaryDirectory() as d:
            data = Path(d)
            _sets(data)
            port = free_tcp_port()
            env = dict(os.environ, EXOSTUDY_DATA_DIR=str(data),
                       EXOSTUDY_DEVICE_ADDRESS=f"127.0.0.1:{free_udp_port()}")
            log = data / "server.log"
            with open(log, "wb") as out:
                t0 = time.monotonic()
                cmd = ([sys.executable, "-c", PREVIOUS, str(port)] if previous else
                       [str(EXOSTUDY), "serve", "--port", str(port), "--log-level", "warning"])
                proc = subprocess.Popen(cmd, cwd=data, env=env,
                                        stdout=out, stderr=subprocess.STDOUT)
            base = f"http://127.0.0.1:{port}"
            times: dict[str, float] = {}
            try:
                with httpx.Client(base_url=base, timeout=30) as c:
                    while "worker" not in times and time.monotonic() - t0 < LIMIT_S:
                        if proc.poll() is not None:
                            raise RuntimeError(f"server exited: {log.read_text()[-2000:]}")
                        try:
                            r = c.get("/api/health")
                        except httpx.HTTPError:
                            time.sleep(0.05)
                            continue
                        now = time.monotonic() - t0
                        times.setdefault("answer", now)
                        times.setdefault("answer_status", float(r.status_code))
                        if r.status_code == 200:
                            if "app" not in times:
                                times["app"] = now
                                times["page_status"] = float(c.get("/login").status_code)
                            if r.json()["worker"]["ticks"] > 0:
                                times["worker"] = now
                        time.sleep(0.05)
                    if "worker" in times:  # what the link dropped over the first seconds
                        time.sleep(STALE_WINDOW_S)
                        drops = c.get("/api/health").json()["device"]["link_drops"]
                        times["device_stale"] = float(drops.get("device_stale", 0))
                        times["host_stale"] = float(drops.get("stale", 0))
            finally:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(30)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(10)
            return times
    finally:
        for p in loops:
            p.kill()
            p.wait()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    load_before = load_average()
    rows: list[list[object]] = []
    for busy in (0, 2):
        for previous in (True, False):
            for _ in range(args.repeats):
                ref = _reference_loop()
                load = load_average()
                t = one_start(busy, previous)
                label = ("quiet" if busy == 0 else "two busy loops") + (
                    ", previous start (baseline)" if previous else ", exostudy serve")
                row = [label, f"{t.get('answer', float('nan')):.1f} "
                       f"({int(t.get('answer_status', 0))})",
                       f"{t.get('app', float('nan')):.1f}", int(t.get("page_status", 0)),
                       f"{t.get('worker', float('nan')):.1f}",
                       int(t.get("device_stale", -1)), f"{ref:.2f}", load]
                print(row, flush=True)
                rows.append(row)
    record("startup", "bench/bench_startup.py " + " ".join(sys.argv[1:]),
           ["beside", "health first answered, s (status)", "application ready (health 200), s",
            "/login status then", "worker ticking, s",
            "commands the device dropped as stale, first 5 s", "reference loop (s)", "(load)"],
           rows, load_before,
           note="Fresh data folder each start (all migrations, the demo study), default sets "
           "copied in, device simulator spawned. While the application loads, every "
           "request gets 503 with Retry-After (health says \"starting\"). Target: health "
           "answers within 10 s beside two busy loops. The spawned device simulator runs "
           "with real-time scheduling where allowed (as the worker's loop does), so it no "
           "longer stalls behind the start-up and judges prompt commands stale "
           "(device_stale; -1: the worker did not tick within the run's limit).")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
