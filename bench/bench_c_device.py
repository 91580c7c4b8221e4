"""The C device (firmware core on Linux, simulated wearer) against the Python reference
device, in the same run, on loopback.

For each implementation, the device runs as its own process with the same arguments
(`firmware/build/exostudy-device` or `python -m controller.sim.device_server`) and this
script plays the worker with `UdpDevice`: it reads each sample and answers at once with
a command (both sides locked 0.3 s of every 2 s, as bench/bench_udp.py). Reports

- the sample-to-command round trip the device measured (send of sample n to arrival
  of the command echoing n), p50/p99/max;
- late samples over the run (sent more than 2 ms after due), as the device counted them;
- the watchdog: `--releases` times, with both solenoids commanded on, the host stops
  commanding (it goes on reading); the release time is from the last command sent to
  the arrival of the first sample whose status says WATCHDOG_RELEASED with both
  solenoids off (an upper bound on the device's own time: loopback adds microseconds).
  The protocol requires 100-110 ms.

    .venv/bin/python bench/bench_c_device.py [--minutes 10] [--releases 10]
        [--script paper-evaluation] [--seed 0] [--only c|python] [--realtime]

The device clock's figure is the released sample's scheduled time minus that of the
sample the last command answered, minus the host's own time from reading that sample
to sending the command: it still exceeds the true command-to-release time by that
sample's lateness and the two loopback hops (together about a round trip), so both
figures are upper bounds; the verdict uses the device clock's.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.record import record  # noqa: E402
from controller.device.auth import load_or_create_key  # noqa: E402
from controller.device.base import LockCommand, Status  # noqa: E402
from controller.device.udp import UdpDevice  # noqa: E402
from controller.sim.device_server import request_realtime  # noqa: E402
from tests import c_device  # noqa: E402
from tests.polling import free_udp_port  # noqa: E402

KEY_FILE = Path(tempfile.gettempdir()) / f"exostudy-bench-c-{os.getuid()}.key"
WATCHDOG_LIMIT_MS = 110.0  # docs/device-protocol.md, safety rule 1


def _pct(values: list[float], q: float) -> float:
    if not values:
        return math.nan
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1)]


def _command(implementation: str, port: int, seed: int, script: str, seconds: float,
             realtime: bool) -> list[str]:
    args = ["--port", str(port), "--seed", str(seed), "--script", script,
            "--duration", str(seconds), "--key-file", str(KEY_FILE)]
    if realtime:
        args.append("--realtime")
    if implementation == "c":
        return [str(c_device.device_binary()), *args, "--python", sys.executable]
    return [sys.executable, "-m", "controller.sim.device_server", *args]


def _first_sample(dev: UdpDevice) -> None:
    deadline = time.monotonic() + 120.0  # interpreter start on a loaded machine
    while time.monotonic() < deadline:
        if dev.read(0.5) is not None:
            return
    raise SystemExit("no sample from the device within 120 s")


def _drive(dev: UdpDevice, seconds: float) -> dict[str, Any]:
    """The worker's side: one command per sample."""
    end = time.monotonic() + seconds
    n = timeouts = 0
    while time.monotonic() < end:
        s = dev.read(0.1)
        if s is None:
            timeouts += 1
            continue
        lock = (s.seq % 200) < 30
        dev.send(LockCommand(seq=s.seq, lock_left=lock, lock_right=lock))
        n += 1
    return {"received": n, "timeouts": timeouts}


def _watchdog(dev: UdpDevice, releases: int) -> tuple[list[float], list[float]]:
    """Release times (ms) after the last command, `releases` times: host-side (command
    sent to released sample received) and on the device's clock (scheduled time of the
    released sample minus that of the sample the last command answered, minus the
    host's time between reading that sample and sending the command)."""
    out: list[float] = []
    device_ms: list[float] = []
    for _ in range(releases):
        # 0.5 s of commands with both solenoids on, until a sample shows them on.
        on_since = time.monotonic()
        energised = False
        while time.monotonic() - on_since < 0.5 or not energised:
            s = dev.read(0.1)
            if s is None:
                continue
            read_at = time.monotonic()
            dev.send(LockCommand(seq=s.seq, lock_left=True, lock_right=True))
            last_command = time.monotonic()
            # The command left this long after sample s arrived: on the device's clock
            # it arrived at least that long after s was due.
            answered_t = s.t + (last_command - read_at)
            energised = bool(s.status & Status.SOLENOID_LEFT and s.status & Status.SOLENOID_RIGHT)
            if time.monotonic() - on_since > 10.0:
                raise SystemExit("the device never showed both solenoids energised")
        # Silence: read on, command nothing.
        deadline = last_command + 1.0
        released_at = released_t = math.nan
        while time.monotonic() < deadline:
            s = dev.read(0.1)
            if s is None:
                continue
            off = not s.status & (Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT)
            if s.status & Status.WATCHDOG_RELEASED and off:
                released_at = time.monotonic()
                released_t = s.t
                break
        out.append(1e3 * (released_at - last_command))
        device_ms.append(1e3 * (released_t - answered_t))
        # Let the mechanism settle unlocked before the next round (the wearer moves on).
        settle = time.monotonic() + 0.3
        while time.monotonic() < settle:
            s = dev.read(0.1)
            if s is not None:
                dev.send(LockCommand(seq=s.seq, lock_left=False, lock_right=False))
    return out, device_ms


def run(implementation: str, minutes: float, releases: int, seed: int, script: str,
        realtime: bool = False) -> dict[str, Any]:
    """One device process: drive it, then the watchdog rounds; its own statistics."""
    port = free_udp_port()
    seconds = 60.0 * minutes
    proc = subprocess.Popen(_command(implementation, port, seed, script, seconds + 600.0,
                                     realtime),
                            cwd=ROOT, stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    dev = UdpDevice(device_port=port, key=load_or_create_key(KEY_FILE))
    try:
        dev.open()
        _first_sample(dev)
        host = _drive(dev, seconds)
        host["watchdog_ms"], host["watchdog_device_ms"] = _watchdog(dev, releases)
        link = dev.stats.copy()
        host.update(gaps=link.gaps, missing=link.missing, malformed=sum(link.malformed.values()))
    finally:
        dev.close()
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=30.0)
    lines = [line for line in out.splitlines() if line.startswith("{")]
    if not lines:
        raise SystemExit(f"{implementation} device printed no statistics (exit {proc.returncode})")
    return {"host": host, "device": json.loads(lines[-1])}


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, run each implementation, print one table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--minutes", type=float, default=10.0, help="per implementation")
    parser.add_argument("--releases", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--script", default="paper-evaluation")
    parser.add_argument("--only", choices=("c", "python"), default=None)
    parser.add_argument("--realtime", action="store_true",
                        help="SCHED_FIFO for this host and both devices (root or "
                        "CAP_SYS_NICE), as firmware on its own core would have")
    args = parser.parse_args(argv)
    scheduling = request_realtime() if args.realtime else "normal"
    load_or_create_key(KEY_FILE)
    c_device.build()
    results: dict[str, dict[str, Any]] = {}
    load0 = os.getloadavg()
    started = time.strftime("%H:%M:%S", time.gmtime())
    for implementation in ("python", "c"):
        if args.only and implementation != args.only:
            continue
        print(f"running the {implementation} device for {args.minutes:g} min ...", flush=True)
        results[implementation] = run(implementation, args.minutes, args.releases, args.seed,
                                      args.script, args.realtime)
    load1 = os.getloadavg()
    print(f"\n{args.minutes:g} min per device, script {args.script} seed {args.seed}, "
          f"started {started} UTC, {os.cpu_count()} CPUs, load {load0[0]:.2f} -> "
          f"{load1[0]:.2f}; host scheduling: {scheduling}")
    print(f"{'':34}" + "".join(f"{name:>28}" for name in results))

    table: list[list[object]] = []

    def row(label: str, fmt: Any) -> None:
        cells = [fmt(r) for r in results.values()]
        table.append([label, *cells])
        print(f"{label:34}" + "".join(f"{c:>28}" for c in cells))

    row("samples sent / received", lambda r: f"{r['device']['samples_sent']} / "
        f"{r['host']['received']}")
    row("round trip p50 / p99 (ms)", lambda r: f"{r['device']['rtt_p50_ms']:.3f} / "
        f"{r['device']['rtt_p99_ms']:.3f}")
    row("round trip max (ms)", lambda r: f"{r['device']['rtt_max_ms']:.3f}")
    row("late samples (> 2 ms)", lambda r: f"{r['device']['late']} "
        f"({100 * r['device']['late_fraction']:.2f} %)")
    row("lateness p50 / p99 (ms)", lambda r: f"{r['device']['lateness_p50_ms']:.3f} / "
        f"{r['device']['lateness_p99_ms']:.3f}")
    row("lateness max (ms)", lambda r: f"{r['device']['lateness_max_ms']:.1f}")
    row("host gaps (missing) / timeouts", lambda r: f"{r['host']['gaps']} "
        f"({r['host']['missing']}) / {r['host']['timeouts']}")
    row("watchdog release min/median/max", lambda r: "{:.1f} / {:.1f} / {:.1f} ms".format(
        min(r["host"]["watchdog_ms"]), _pct(r["host"]["watchdog_ms"], 50),
        max(r["host"]["watchdog_ms"])))
    row("  on the device clock", lambda r: "{:.1f} / {:.1f} / {:.1f} ms".format(
        min(r["host"]["watchdog_device_ms"]), _pct(r["host"]["watchdog_device_ms"], 50),
        max(r["host"]["watchdog_device_ms"])))
    row("wearer step max / over 1 ms (C)", lambda r: (
        f"{r['device']['wearer_step_max_ms']:.2f} ms / {r['device']['wearer_slow_steps']}"
        if "wearer_step_max_ms" in r["device"] else "(in process)"))
    row("device watchdog releases", lambda r: str(r["device"]["watchdog_releases"]))
    print()
    for name, r in results.items():
        worst = max(r["host"]["watchdog_device_ms"])
        verdict = "within" if worst <= WATCHDOG_LIMIT_MS else "OVER"
        print(f"{name}: worst watchdog release on the device clock {worst:.2f} ms, {verdict} "
              f"the {WATCHDOG_LIMIT_MS:g} ms bound (host side: "
              f"{max(r['host']['watchdog_ms']):.2f} ms)")
    command = "bench/bench_c_device.py " + " ".join(sys.argv[1:] if argv is None else argv)
    record("c_device", command.strip(), ["", *results], table, round(load0[0], 1),
           note=f"{args.minutes:g} min per device, script {args.script} seed {args.seed}; "
                f"host scheduling: {scheduling}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
