"""Check a device end to end with ExoStudy's real host link, `UdpDevice`: start the
device command given after `--`, then see samples arrive, a lock command show up as
SOLENOID_LEFT, and the device's command watchdog release it once commands stop; with
--hardware-release also the bring-up probe of the heartbeat release.

Used with tap-bench (the Nucleo port's network stack and the core on a Linux TAP
interface, through the kernel's ARP/IPv4/UDP) and with exo-sbc under a fake-hardware
shim (the SBC port's real loop over loopback). See the ports' Makefiles.

    python link_check.py --key-file K --device-host H [--device-port P]
        [--local-host L] [--wait-ready] -- COMMAND...

Prints what it saw and exits non-zero if a check failed.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from controller.device.auth import load_key
from controller.device.base import LockCommand, Sample, Status
from controller.device.udp import UdpDevice


def _expect(cond: bool, what: str, failures: list[str]) -> None:
    print(("ok    " if cond else "FAIL  ") + what)
    if not cond:
        failures.append(what)


def _exercise(dev: UdpDevice, failures: list[str]) -> None:
    samples: list[Sample] = []
    first = dev.read(5.0)
    _expect(first is not None, "a sample arrived (addresses, framing and tag right)", failures)
    if first is None:
        return
    samples.append(first)
    _expect(bool(first.status & Status.WATCHDOG_RELEASED),
            "WATCHDOG_RELEASED before the first command", failures)
    # 0.5 s of commands, locking the left side after 0.2 s.
    t0 = time.monotonic()
    locked_seen = False
    while time.monotonic() - t0 < 0.5:
        s = dev.read(0.1)
        if s is None:
            continue
        samples.append(s)
        dev.send(LockCommand(seq=s.seq, lock_left=time.monotonic() - t0 > 0.2,
                             lock_right=False))
        locked_seen |= bool(s.status & Status.SOLENOID_LEFT)
    _expect(locked_seen, "SOLENOID_LEFT reported after a lock command", failures)
    # Stop commanding: the device's watchdog must release within about 110 ms.
    t_stop = time.monotonic()
    released_after = None
    while time.monotonic() - t_stop < 0.5:
        s = dev.read(0.1)
        if s is None:
            continue
        samples.append(s)
        if s.status & Status.WATCHDOG_RELEASED and not s.status & Status.SOLENOID_LEFT:
            released_after = time.monotonic() - t_stop
            break
    _expect(released_after is not None, "the command watchdog released the solenoid",
            failures)
    if released_after is not None:
        print(f"      released {released_after * 1000:.0f} ms after the last command")
    seqs = [s.seq for s in samples]
    _expect(seqs == sorted(seqs), "sample sequence increases", failures)
    _expect(all(0 <= c <= 16383 for s in samples for c in s.counts), "counts within 14 bits",
            failures)
    _expect(not any(s.status & Status.ENCODER_FAULT for s in samples),
            "no encoder fault (SPI framing and parity right)", failures)
    print(f"      {len(samples)} samples, link counters {dev.link_counters()}")


def _hardware_release(dev: UdpDevice, failures: list[str]) -> None:
    """The bring-up step "hardware release" against a device whose drivers' enable is
    modelled (exo-sbc's GPIO shim holds it 30 ms after each heartbeat edge): hold the
    left lock, stop the heartbeat, time HEARTBEAT_STOPPED -> DRIVERS_OFF in device time."""
    seen: list[Sample] = []

    def run(seconds: float, stop: bool, lock: bool) -> None:
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            s = dev.read(0.1)
            if s is None:
                continue
            seen.append(s)
            dev.send(LockCommand(seq=s.seq, lock_left=lock, lock_right=False,
                                 stop_heartbeat=stop))

    run(0.3, stop=False, lock=True)
    running = list(seen)
    _expect(bool(running) and not any(s.status & Status.DRIVERS_OFF for s in running[5:]),
            "drivers enabled while the heartbeat runs", failures)
    seen.clear()
    run(0.3, stop=True, lock=True)
    stopped = next((s for s in seen if s.status & Status.HEARTBEAT_STOPPED), None)
    off = next((s for s in seen if s.status & Status.DRIVERS_OFF), None)
    _expect(stopped is not None, "HEARTBEAT_STOPPED after a STOP_HEARTBEAT command", failures)
    _expect(off is not None, "DRIVERS_OFF once the heartbeat stopped", failures)
    if stopped is not None and off is not None:
        release_ms = (off.t - stopped.t) * 1000
        print(f"      hardware release {release_ms:.0f} ms after HEARTBEAT_STOPPED")
        _expect(10 <= release_ms <= 40, "release within 10-40 ms (the bring-up threshold)",
                failures)
    seen.clear()
    run(0.3, stop=False, lock=False)
    _expect(bool(seen) and not seen[-1].status & (Status.DRIVERS_OFF | Status.HEARTBEAT_STOPPED),
            "heartbeat and drivers back after the probe", failures)


def main(argv: list[str]) -> int:
    """Run the device command and check it; 0 if every check passed."""
    if "--" not in argv:
        print("usage: link_check.py OPTIONS -- COMMAND...", file=sys.stderr)
        return 2
    split = argv.index("--")
    p = argparse.ArgumentParser()
    p.add_argument("--key-file", required=True)
    p.add_argument("--device-host", required=True)
    p.add_argument("--device-port", type=int, default=47300)
    p.add_argument("--local-host", default=None)
    p.add_argument("--wait-ready", action="store_true",
                   help="wait for a line starting with 'ready' on the command's stdout")
    p.add_argument("--hardware-release", action="store_true",
                   help="also run the hardware-release probe (a device with a modelled "
                        "heartbeat monostable and readback)")
    args = p.parse_args(argv[:split])
    key = load_key(Path(args.key_file))
    proc = subprocess.Popen(argv[split + 1:], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    if args.wait_ready:
        for line in proc.stdout:
            if line.startswith("ready"):
                break
    failures: list[str] = []
    dev = UdpDevice(device_host=args.device_host, device_port=args.device_port, key=key,
                    local_host=args.local_host)
    try:
        dev.open()
        _exercise(dev, failures)
        if args.hardware_release:
            _hardware_release(dev, failures)
    finally:
        dev.close()
        proc.terminate()
        out, _ = proc.communicate(timeout=10)
        print(out.strip())
    _expect(proc.returncode == 0, f"the device exited cleanly (status {proc.returncode})",
            failures)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
