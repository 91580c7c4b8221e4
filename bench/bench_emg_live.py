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

`--cpu`: the server's CPU for recording live EMG instead, in CPU seconds per minute of
16 channels at 2 kHz, without a server: one process pushes synthetic EMG on an LSL
outlet in blocks of a given size and pulls each block through an inlet as
`backend.emg.live.EmgInlet` does (`pull` into the stream's array, montage order, volts),
then hands it to what a recording does with it: the file (`EmgWriter.append`), the
quality (`QualitySummary.add`) and the live strip (`LiveEnvelope.push`, a message every
40 ms of data, as the dict handed to the WebSocket; its JSON encoding is left out).
Blocks of 20 samples are the amplifier's 10 ms chunks at real time; 2048 the largest
pull, as in a sped-up virtual study. The time is the pulling thread's own (liblsl's
network threads and the push are left out).

    .venv/bin/python bench/bench_emg_live.py --cpu [--seconds 60]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
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


#: The recording path's parts, as timed by `cpu_per_minute`.
PARTS = ("pull", "file", "quality", "strip")


def _synthetic_emg(n: int, fs: float, channels: int) -> np.ndarray:
    """Noise at surface-EMG amplitude with 1 s bursts every 2 s (float32, as sent)."""
    rng = np.random.default_rng(7)
    burst = 1.0 + 4.0 * (np.sin(2 * np.pi * 0.5 * np.arange(n) / fs)[:, None] > 0.3)
    return np.asarray(rng.normal(0, 30e-6, (n, channels)) * burst, dtype=np.float32)


def cpu_per_minute(block: int, seconds: float, fs: float = 2000.0,
                   channels: int = 16) -> tuple[dict[str, float], int]:
    """CPU seconds per minute of EMG of each part of the recording path, and the
    number of pulls, for the amplifier pushing `block` samples at a time."""
    from backend.emg import live
    from backend.emg.live_envelope import LiveEnvelope
    from backend.emg.quality_summary import QualitySummary
    from backend.emg.store import EmgWriter

    source = f"bench-emg-cpu-{uuid.uuid4().hex[:8]}"
    info = pylsl.StreamInfo(f"BenchCPU-{source}", "EMG", channels, fs, pylsl.cf_float32,
                            source)
    outlet = pylsl.StreamOutlet(info, chunk_size=block)
    (found,) = pylsl.resolve_bypred(f"source_id='{source}'", 1, 10.0)
    inlet = pylsl.StreamInlet(found, max_buflen=360, recover=False)
    inlet.open_stream(timeout=10.0)
    x = _synthetic_emg(int(fs * seconds), fs, channels)
    t0 = pylsl.local_clock()
    labels = [f"ch{i}" for i in range(channels)]
    cols, volts = np.arange(channels), np.ones(channels)
    buf = live.pull_buffer(found)
    data_time = [0.0]
    sent: list[dict[str, object]] = []
    strip = LiveEnvelope(fs, labels, 1, 1, publish=sent.append, clock=lambda: data_time[0])
    cpu = dict.fromkeys(PARTS, 0.0)
    pulls = got = 0
    with tempfile.TemporaryDirectory(prefix="bench-emg-cpu-") as tmp:
        writer = EmgWriter(Path(tmp) / "1.emgc", labels, fs)
        quality = QualitySummary(fs, labels)
        for i in range(0, x.shape[0], block):
            part = x[i:i + block]
            outlet.push_chunk(part, (t0 + (i + np.arange(part.shape[0])) / fs).tolist())
            data_time[0] = (i + part.shape[0]) / fs
            while got < i + part.shape[0]:
                c0 = time.thread_time()
                ts = live.pull(inlet, buf)
                if not ts:
                    continue
                t = np.asarray(ts, dtype=np.float64) + inlet.time_correction(timeout=1.0)
                samples = buf[:len(ts), cols] * volts
                c1 = time.thread_time()
                writer.append(t, samples)
                c2 = time.thread_time()
                quality.add(t, samples)
                c3 = time.thread_time()
                strip.push(t, samples)
                c4 = time.thread_time()
                for name, dt in zip(PARTS, (c1 - c0, c2 - c1, c3 - c2, c4 - c3), strict=True):
                    cpu[name] += dt
                got += len(ts)
                pulls += 1
        c0 = time.thread_time()
        writer.close()
        c1 = time.thread_time()
        quality.finish()
        cpu["file"] += c1 - c0
        cpu["quality"] += time.thread_time() - c1
    inlet.close_stream()
    del inlet, outlet
    return {k: v * 60.0 / seconds for k, v in cpu.items()}, pulls


def cpu_main(seconds: float) -> int:
    """`--cpu`: the table of CPU per minute of EMG for three block sizes."""
    load0 = load_average()
    cpu_per_minute(20, 1.0)  # compiled kernels loaded, liblsl started
    rows: list[list[object]] = []
    for block in (20, 200, 2048):
        per, pulls = cpu_per_minute(block, seconds)
        rows.append([block, pulls, *(f"{per[k]:.3f}" for k in PARTS),
                     f"{sum(per.values()):.3f}"])
    columns = ["amplifier block (samples)", "pulls", "pull (s/min)", "file (s/min)",
               "quality (s/min)", "strip (s/min)", "total (s/min)"]
    print("| " + " | ".join(columns) + " |")
    print("|" + " --- |" * len(columns))
    for r in rows:
        print("| " + " | ".join(str(c) for c in r) + " |")
    note = (f"CPU seconds of the pulling thread per minute of 16 channels at 2 kHz, "
            f"{seconds:g} s of EMG per row; the file's part is mostly zlib (level 1)")
    print(note)
    path = record("emg_live_cpu", " ".join(["bench/bench_emg_live.py", *sys.argv[1:]]),
                  columns, rows, load0, note)
    print(f"recorded in {path}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=None,
                    help="of latency measured (30), or of EMG per row with --cpu (60)")
    ap.add_argument("--cpu", action="store_true",
                    help="CPU per minute of EMG of the recording path, no server")
    args = ap.parse_args()
    if args.cpu:
        return cpu_main(args.seconds or 60.0)
    args.seconds = args.seconds or 30.0
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
