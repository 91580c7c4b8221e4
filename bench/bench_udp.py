"""Benchmark the UDP device link on loopback: round trip and emulator lateness.

Runs the simulated exoskeleton in its own process (`python -m controller.sim.device_server`,
exactly what `exostudy device-sim` runs) and plays the worker against it with `UdpDevice`:
read each sample, answer with a command at once. Reports

- the sample-to-command round trip measured by the device (send of sample n to arrival
  of the command echoing n), p50/p99/max;
- the host's own read-to-send time;
- the emulator's lateness: fraction of samples sent more than 2 ms after they were due;
- link counters (gaps, malformed, foreign).

`--model still` swaps the simulated wearer for a motionless exoskeleton, to separate the
cost of the link from the cost of the simulation.

    .venv/bin/python bench/bench_udp.py --minutes 1 [--realtime] [--model still]
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import tempfile  # noqa: E402

from controller.device.auth import load_or_create_key  # noqa: E402
from controller.device.base import SAMPLE_PERIOD_S, LockCommand, Sample, Status  # noqa: E402
from controller.device.udp import UdpDevice  # noqa: E402
from controller.sim.device_server import request_realtime  # noqa: E402
from tests.polling import free_udp_port  # noqa: E402


class StillExoskeleton:
    """A wearer standing still: the link and the pacing without any simulation cost."""

    dt = SAMPLE_PERIOD_S
    finished = False

    def __init__(self) -> None:
        self.k = 0

    def tick(self, command: LockCommand | None) -> Sample:
        """Constant counts; mechanism state follows the solenoids."""
        self.k += 1
        status = Status.NONE
        if command is not None and command.lock_left:
            status |= Status.LOCKED_LEFT
        if command is not None and command.lock_right:
            status |= Status.LOCKED_RIGHT
        return Sample(
            seq=self.k, t=self.k * self.dt, counts=(3100, 3100, 12900, 12900), status=status
        )


#: The link key host and emulator share (protocol version 2 authenticates every packet).
KEY_FILE = Path(tempfile.gettempdir()) / f"exostudy-bench-{os.getuid()}.key"


def _serve_still(port: int, duration: float, queue: Any, stop: Any) -> None:
    from controller.sim.device_server import serve

    model = StillExoskeleton()
    stats = serve(port, 0, "still", duration=duration, stop_event=stop, model=model,
                  key=load_or_create_key(KEY_FILE))
    queue.put(stats.summary())


def _pct(values: list[float], q: float) -> float:
    if not values:
        return math.nan
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1)]


def _drive(port: int, seconds: float) -> dict[str, Any]:
    """The worker's side: one command per sample, locking both sides 0.3 s of every 2 s."""
    host_s: list[float] = []
    dev = UdpDevice(device_port=port, key=load_or_create_key(KEY_FILE))
    dev.open()
    try:
        first = None
        deadline = time.monotonic() + 120.0  # the simulator may take a while to start
        while first is None and time.monotonic() < deadline:
            first = dev.read(0.5)
        if first is None:
            raise SystemExit("no sample from the device within 120 s")
        end = time.monotonic() + seconds
        n = 0
        timeouts = 0
        while time.monotonic() < end:
            s = dev.read(0.1)
            if s is None:
                timeouts += 1
                continue
            t0 = time.perf_counter()
            lock = (s.seq % 200) < 30
            dev.send(LockCommand(seq=s.seq, lock_left=lock, lock_right=lock))
            host_s.append(time.perf_counter() - t0)
            n += 1
        stats = dev.stats.copy()
    finally:
        dev.close()
    return {
        "received": n,
        "timeouts": timeouts,
        "gaps": stats.gaps,
        "missing": stats.missing,
        "duplicates": stats.duplicates,
        "stale": stats.stale,
        "malformed": sum(stats.malformed.values()),
        "foreign": stats.foreign,
        "host_p50_ms": 1e3 * _pct(host_s, 50),
        "host_p99_ms": 1e3 * _pct(host_s, 99),
    }


def run(
    minutes: float, seed: int, script: str, model: str, realtime: bool = False
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Start the emulator process, drive it for `minutes`, stop it; (host, device) results."""
    port = free_udp_port()
    seconds = 60.0 * minutes
    load_or_create_key(KEY_FILE)
    if model == "still":
        ctx = multiprocessing.get_context("spawn")
        queue = ctx.Queue()
        stop = ctx.Event()
        proc = ctx.Process(target=_serve_still, args=(port, seconds + 600.0, queue, stop))
        proc.start()
        host = _drive(port, seconds)
        stop.set()
        device = queue.get(timeout=30.0)
        proc.join(10.0)
        return host, device
    cmd = [
        sys.executable, "-m", "controller.sim.device_server",
        "--port", str(port), "--seed", str(seed), "--script", script,
        "--duration", str(seconds + 600.0), "--key-file", str(KEY_FILE),
    ] + (["--realtime"] if realtime else [])  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    server = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    try:
        host = _drive(port, seconds)
        server.send_signal(signal.SIGTERM)
        out, _ = server.communicate(timeout=30.0)
    finally:
        if server.poll() is None:
            server.kill()
    if server.returncode != 0:
        raise SystemExit(f"device-sim exited with {server.returncode}")
    return host, json.loads(out.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, run once, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--minutes", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--script", default="paper-evaluation")
    parser.add_argument("--model", choices=("sim", "still"), default="sim")
    parser.add_argument(
        "--realtime", action="store_true", help="SCHED_FIFO for host and emulator (root)"
    )
    args = parser.parse_args(argv)
    scheduling = "normal"
    if args.realtime:
        # Before the emulator starts: a spawned "still" emulator inherits the policy.
        scheduling = request_realtime()
    load0 = os.getloadavg()
    t0 = time.time()
    host, dev = run(args.minutes, args.seed, args.script, args.model, args.realtime)
    load1 = os.getloadavg()
    h, d = host, dev
    started = time.strftime("%H:%M:%S", time.gmtime(t0))
    rtt = f"{d['rtt_p50_ms']:.3f} / {d['rtt_p99_ms']:.3f} / {d['rtt_max_ms']:.3f} ms"
    late = f"{d['lateness_p50_ms']:.3f} / {d['lateness_p99_ms']:.3f} / {d['lateness_max_ms']:.3f}"
    dup_stale = f"{h['duplicates']} / {h['stale']}"
    sent = d["samples_sent"]
    rows = [
        ("model / script", f"{args.model} / {args.script} (seed {args.seed})"),
        ("duration", f"{args.minutes:g} min, started {started} UTC"),
        ("host scheduling", scheduling),
        ("CPUs / load avg start -> end", f"{os.cpu_count()} / {load0[0]:.2f} -> {load1[0]:.2f}"),
        ("samples sent / received", f"{d['samples_sent']} / {h['received']}"),
        ("gaps (missing) / dup / stale", f"{h['gaps']} ({h['missing']}) / {dup_stale}"),
        ("malformed / foreign (host)", f"{h['malformed']} / {h['foreign']}"),
        ("read timeouts (100 ms)", f"{h['timeouts']}"),
        ("round trip p50 / p99 / max", f"{rtt} (n={d['rtt_n']})"),
        ("host read->send p50 / p99", f"{h['host_p50_ms']:.3f} / {h['host_p99_ms']:.3f} ms"),
        ("late (> 2 ms) fraction", f"{d['late_fraction']:.5f} ({d['late']} of {sent})"),
        ("lateness p50 / p99 / max", f"{late} ms"),
        ("schedule resyncs", f"{d['resyncs']}"),
        ("watchdog releases", f"{d['watchdog_releases']}"),
    ]  # fmt: skip
    width = max(len(k) for k, _ in rows)
    print(f"{'metric':<{width}}  value")
    print(f"{'-' * width}  {'-' * 40}")
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
