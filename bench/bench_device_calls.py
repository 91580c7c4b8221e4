"""Benchmark the device calls a control tick makes, each beside a baseline in the same run.

The unit tests check what these calls do (a send never waits, a read waits out its
timeout, a free-running simulated device is not paced); how long they take depends on
the machine and its load, so it is measured here instead:

- `UdpDevice.send` to a device that never reads (2,000 commands, the kernel's buffer
  fills and drops) against a bare non-blocking `sendto` of the same bytes;
- `UdpDevice.read(0.05)` with nothing to read: the overshoot past the timeout, against
  `select` on an idle socket with the same timeout;
- `SimulatedDevice.read` free running (200 samples, as the worker reads them) against
  calling the simulated exoskeleton's `tick` directly.

    .venv/bin/python bench/bench_device_calls.py [--repeats 20]
"""

from __future__ import annotations

import argparse
import select
import socket
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controller.device.base import NO_LOCK, SAMPLE_PERIOD_S, Sample
from controller.device.protocol import (
    CommandPacket,
    decode_frame,
    encode_command,
    encode_sample,
)
from controller.device.udp import UdpDevice
from controller.sim.exoskeleton import SimulatedExoskeleton
from controller.sim.simulated_device import SimulatedDevice

KEY = bytes(range(32))
SENDS = 2000
READS = 200
TIMEOUT_S = 0.05


def _median_ms(run: Callable[[], float], repeats: int) -> tuple[float, float]:
    """(median, max) in ms of `repeats` calls of `run`, which returns seconds."""
    values = [1e3 * run() for _ in range(repeats)]
    return statistics.median(values), max(values)


def _linked() -> tuple[UdpDevice, socket.socket]:
    """A UdpDevice that has heard one authentic sample from a device socket that will
    never read again (so its commands are addressed, and pile up unread)."""
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(("127.0.0.1", 0))
    peer.settimeout(2.0)
    dev = UdpDevice(device_host="127.0.0.1", device_port=int(peer.getsockname()[1]), key=KEY)
    dev.open()
    hello, host = peer.recvfrom(2048)
    sample = Sample(seq=1, t=SAMPLE_PERIOD_S, counts=(1, 2, 3, 4))
    peer.sendto(encode_sample(sample, KEY, 0x5EED, decode_frame(hello, KEY).sender), host)
    if dev.read(1.0) is None:
        raise RuntimeError("the device's sample did not arrive")
    return dev, peer


def sends(repeats: int) -> None:
    dev, peer = _linked()
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    raw.setblocking(False)
    data = encode_command(CommandPacket(1, False, False), KEY, 1, 0x5EED)
    target = peer.getsockname()

    def device() -> float:
        t0 = time.perf_counter()
        for _ in range(SENDS):
            dev.send(NO_LOCK)
        return time.perf_counter() - t0

    def bare() -> float:
        t0 = time.perf_counter()
        for _ in range(SENDS):
            try:
                raw.sendto(data, socket.MSG_DONTWAIT, target)
            except OSError:
                pass
        return time.perf_counter() - t0

    d, d_max = _median_ms(device, repeats)
    b, _ = _median_ms(bare, repeats)
    print(f"UdpDevice.send x{SENDS} to a device that never reads: median {d:.1f} ms "
          f"(max {d_max:.1f}), {1e3 * d / SENDS:.1f} us per send; bare sendto {b:.1f} ms "
          f"({d / b:.1f}x); dropped by the kernel: {dev.stats.send_errors}", flush=True)
    dev.close()
    peer.close()
    raw.close()


def read_timeouts(repeats: int) -> None:
    dev, peer = _linked()
    idle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    idle.bind(("127.0.0.1", 0))

    def device() -> float:
        t0 = time.monotonic()
        if dev.read(TIMEOUT_S) is not None:
            raise RuntimeError("nothing should have arrived")
        return time.monotonic() - t0 - TIMEOUT_S

    def bare() -> float:
        t0 = time.monotonic()
        select.select([idle], [], [], TIMEOUT_S)
        return time.monotonic() - t0 - TIMEOUT_S

    d, d_max = _median_ms(device, repeats)
    b, b_max = _median_ms(bare, repeats)
    print(f"UdpDevice.read({TIMEOUT_S}) with nothing to read, past the timeout: median "
          f"{d:.2f} ms (max {d_max:.2f}); select on an idle socket {b:.2f} ms "
          f"(max {b_max:.2f})", flush=True)
    dev.close()
    peer.close()
    idle.close()


def simulated_reads(repeats: int) -> None:
    def device() -> float:
        dev = SimulatedDevice(seed=1, script="walking", realtime=False, loop=False)
        with dev:
            t0 = time.perf_counter()
            for _ in range(READS):
                dev.read(1.0)
            return time.perf_counter() - t0

    def bare() -> float:
        exo = SimulatedExoskeleton(seed=1, script="walking", loop=False)
        t0 = time.perf_counter()
        for _ in range(READS):
            exo.tick(None)
        return time.perf_counter() - t0

    device()  # compile and load once, for both
    bare()
    d, d_max = _median_ms(device, repeats)
    b, _ = _median_ms(bare, repeats)
    print(f"SimulatedDevice.read x{READS}, free running: median {d:.1f} ms (max {d_max:.1f}), "
          f"{READS * SAMPLE_PERIOD_S / (d / 1e3):.0f}x real time; the exoskeleton's tick alone "
          f"{b:.1f} ms ({d / b:.2f}x)", flush=True)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=20)
    args = p.parse_args()
    sends(args.repeats)
    read_timeouts(args.repeats)
    simulated_reads(args.repeats)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
