"""Live EMG envelope latency: from the amplifier's push on LSL to the envelope message
received by a console's WebSocket (target: under 100 ms).

Set-up as `make run` (bench/server_rig.py: server, worker, simulated exoskeleton over
UDP). The simulated amplifier (`controller.sim.emg_amplifier.EmgTap`, 16 channels at
2 kHz, 20-sample chunks every 10 ms) runs in a process of its own, as a lab's amplifier
software would; a session subscribes to it through the API; a WebSocket client in this
process reads `/ws/live` and, for each `emg` message, takes liblsl's clock at receipt
minus

- `t_end`, the stamp of the newest raw sample the message includes: the latency of the
  amplifier's push to the console;
- the stamp of the message's newest envelope value (on the 50 Hz display grid, so up
  to 20 ms older than the newest sample): the age of what the strip draws last.

The amplifier process stamps each chunk with liblsl's clock just before pushing it
(rather than with its tick's scheduled time), so the figures start at the push itself.
All clocks are liblsl's `local_clock` on this machine. The server adds liblsl's clock
correction to the stamps (an estimate from round trips, which a loaded machine makes
non-zero although both ends share the clock); each message says which correction it
used, and the latency is taken against the amplifier's own stamp. The server runs in
this process (uvicorn in a thread), as in the other console benchmarks.

    .venv/bin/python bench/bench_emg_live.py [--seconds 30]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
# liblsl on this machine only (the tests' configuration); the amplifier inherits it.
os.environ.setdefault("LSLAPICFG", str(ROOT / "tests" / "backend" / "lab" / "lsl_api.cfg"))

import httpx  # noqa: E402
import numpy as np  # noqa: E402
import pylsl  # noqa: E402
from websockets.sync.client import connect  # noqa: E402

from bench.record import load_average, record  # noqa: E402
from bench.server_rig import running_server  # noqa: E402
from controller.sim.emg_amplifier import channel_labels  # noqa: E402
from tests.login import PASSWORD, USERNAME  # noqa: E402
from tests.polling import wait_for  # noqa: E402

#: The amplifier process: the simulated wearer's EMG at the tick schedule.
AMPLIFIER = """
import sys, time
from controller.sim.emg_amplifier import RESYNC_S, EmgTap
from controller.sim.exoskeleton import SimulatedExoskeleton
tap = EmgTap(SimulatedExoskeleton(seed=5, script="paper-evaluation"), name="BenchEMG",
             source_id=sys.argv[1])
tap.start()
# Stamp each chunk with the clock at its push (not the tick schedule), so the benchmark
# measures from the push itself.
import pylsl
tap._stamp = lambda k: pylsl.local_clock()
next_t = time.monotonic()
while True:
    tap.tick(None)
    next_t += tap.dt
    # Behind by more than the tap's resync threshold: start the schedule again from now,
    # as the tap restarts its stamps (a burst of catch-up ticks would stamp ahead).
    if time.monotonic() - next_t > RESYNC_S:
        next_t = time.monotonic()
    time.sleep(max(0.0, next_t - time.monotonic()))
"""


def _montage() -> dict[str, object]:
    chans = []
    for label in channel_labels()[:12]:
        muscle, _, side = label.rpartition("_")
        chans.append({"label": label, "muscle": muscle, "side": side})
    return {"placement_scheme": "SENIAM", "channels": chans}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0)
    args = ap.parse_args()
    load0 = load_average()
    source = f"bench-emg-{uuid.uuid4().hex[:8]}"
    amp = subprocess.Popen([sys.executable, "-c", AMPLIFIER, source], cwd=ROOT)
    try:
        with running_server() as srv:
            token = httpx.post(f"{srv.base}/api/auth/token", timeout=60, json={
                "username": USERNAME, "password": PASSWORD}).json()["access_token"]
            api = httpx.Client(base_url=srv.base, timeout=60,
                               headers={"Authorization": f"Bearer {token}"})

            def ok(r: httpx.Response) -> dict[str, object]:
                assert r.is_success, r.text
                out: dict[str, object] = r.json()
                return out

            study = ok(api.post("/api/studies", json={"name": "EMG latency"}))["id"]
            ok(api.put(f"/api/studies/{study}/emg-montage", json=_montage()))
            pid = ok(api.post(f"/api/studies/{study}/participants", json={"code": "B1"}))["id"]
            sess = ok(api.post(f"/api/participants/{pid}/sessions",
                               json={"kind": "evaluation", "precompression_pct": 25}))["id"]
            wait_for(lambda: api.post(f"/api/sessions/{sess}/emg-streams", json={
                "name": "BenchEMG", "source_id": source,
                "ignore_labels": channel_labels()[12:]}).status_code == 201, 60,
                "the amplifier visible and subscribed", poll=1.0)
            cookie = "; ".join(f"{k}={v}" for k, v in srv.cookies.items())
            ws_url = srv.base.replace("http://", "ws://") + "/ws/live"
            push: list[float] = []
            shown: list[float] = []
            values = 0
            corrections: list[float] = []
            with connect(ws_url, additional_headers={"Cookie": cookie},
                         max_size=None) as ws:
                end = time.monotonic() + args.seconds
                warm = time.monotonic() + 3.0  # the inlet connects, the first pulls
                while time.monotonic() < end:
                    text = ws.recv(timeout=5)
                    now = pylsl.local_clock()
                    msg = json.loads(text)
                    if msg.get("type") != "emg" or time.monotonic() < warm:
                        continue
                    # The amplifier's own stamps: liblsl's correction under this
                    # machine's load is not zero (it is estimated from round trips).
                    own = msg["clock_correction_s"]
                    push.append(now - (msg["t_end"] - own))
                    shown.append(now - (msg["t"][-1] - own))
                    corrections.append(own)
                    values += len(msg["t"])
            health = srv.health()
    finally:
        amp.kill()
        amp.wait()
    p = np.asarray(push) * 1e3
    s = np.asarray(shown) * 1e3
    rate = len(p) / (args.seconds - 3.0)
    rows: list[list[object]] = [
        ["amplifier push of the newest sample -> message received", f"{np.median(p):.1f}",
         f"{np.percentile(p, 95):.1f}", f"{p.max():.1f}", len(p)],
        ["newest envelope value (50 Hz grid) -> message received", f"{np.median(s):.1f}",
         f"{np.percentile(s, 95):.1f}", f"{s.max():.1f}", len(s)],
    ]
    note = (f"{rate:.1f} EMG messages/s, {values / (args.seconds - 3.0):.0f} envelope "
            f"values/s per channel; 16 channels at 2 kHz (12 in the montage); worker "
            f"overruns {health['worker']['overruns']}; liblsl clock correction "
            f"{np.median(corrections) * 1e3:.1f} ms (median, removed)")
    print("| latency | median (ms) | p95 (ms) | max (ms) | messages |")
    print("| --- | --- | --- | --- | --- |")
    for r in rows:
        print("| " + " | ".join(str(c) for c in r) + " |")
    print(note)
    path = record("emg_live", "bench/bench_emg_live.py " + " ".join(sys.argv[1:]),
                  ["latency", "median (ms)", "p95 (ms)", "max (ms)", "messages"], rows,
                  load0, note)
    print(f"recorded in {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
