"""The device firmware on an emulated Cortex-M7: the portable core, the Nucleo port's
network stack and a LAN9118 driver, cross-compiled (firmware/ports/mps2-an500) and
booted in QEMU's mps2-an500 machine, reached through QEMU's user-mode networking.

The project's `UdpDevice` joins it, receives its samples and energises its solenoid
outputs; a tap between the two (an attacker on the link, without the key) records,
forges, replays and holds back real datagrams, and none of that energises anything.
No timing is asserted: the emulator runs on a shared machine, so every wait is on
progress (the console's boot line, the device's own counters and clock in its
samples), with deadlines that only turn a hang into a failure.
"""

from __future__ import annotations

import hashlib
import hmac
import select
import shutil
import socket
import struct
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

from controller.device.auth import key_id, simulated_unique_id
from controller.device.base import LockCommand, Sample, Status
from controller.device.udp import UdpDevice
from tests.polling import free_udp_port, wait_for

ROOT = Path(__file__).resolve().parents[2]
PORT_DIR = ROOT / "firmware" / "ports" / "mps2-an500"
ELF = ROOT / "firmware" / "build" / "mps2-an500" / "exo-mps2.elf"
BLOCK_ADDRESS = "0x003FF000"  # the linker script's emulation block
BOOT_LINE = "running: waiting for the host"
FIRMWARE = "exo-mps2 3"
SOLENOIDS = Status.SOLENOID_LEFT | Status.SOLENOID_RIGHT
SAMPLE, COMMAND, HELLO, CHALLENGE, JOIN = 1, 2, 3, 4, 5
TAG = 32

pytestmark = pytest.mark.skipif(
    shutil.which("qemu-system-arm") is None,
    reason="qemu-system-arm is not installed (Debian package qemu-system-arm; "
           "`make test` installs it through the Makefile's system-firmware target)")


@dataclass(frozen=True)
class Emulator:
    """The booted firmware: where the host reaches it, its key, and its console."""

    port: int
    key: bytes
    console: list[str]


@pytest.fixture(scope="module")
def emulator(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Emulator]:
    """Build the port, write a fresh emulation block (new boot seed), boot QEMU and wait
    for the firmware's boot line; stopped at the end of the module."""
    build = subprocess.run(["make", "-s", "-C", str(PORT_DIR)], capture_output=True,
                           text=True, timeout=300)
    assert build.returncode == 0, (
        f"building the mps2-an500 port failed:\n{build.stdout}\n{build.stderr}")
    folder = tmp_path_factory.mktemp("qemu")
    key_file = folder / "device.key"
    key = bytes(range(100, 132))
    key_file.write_text(key.hex() + "\n")
    key_file.chmod(0o600)
    block = folder / "emu-block.bin"
    subprocess.run([sys.executable, str(PORT_DIR / "tools" / "emu_block.py"),
                    "--key-file", str(key_file), "--out", str(block)], check=True, timeout=30)
    port = free_udp_port()
    proc = subprocess.Popen(
        ["qemu-system-arm", "-M", "mps2-an500", "-nographic", "-monitor", "none",
         "-kernel", str(ELF),
         "-device", f"loader,file={block},addr={BLOCK_ADDRESS},force-raw=on",
         "-nic", f"user,model=lan9118,hostfwd=udp:127.0.0.1:{port}-:47300"],
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    console: list[str] = []
    out = proc.stdout
    assert out is not None
    threading.Thread(target=lambda: console.extend(iter(out.readline, "")), daemon=True).start()
    try:
        try:
            wait_for(lambda: any(BOOT_LINE in line for line in console)
                     or proc.poll() is not None,
                     30, "the firmware's boot line on the emulated console")
        except AssertionError as exc:
            raise AssertionError(f"{exc}; the console said:\n{''.join(console)}") from None
        assert proc.poll() is None, "QEMU stopped:\n" + "".join(console)
        yield Emulator(port, key, console)
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


@dataclass(frozen=True)
class WireSample:
    """A SAMPLE as the tap read it off the wire: what the device itself reports."""

    t_us: int
    seq: int
    status: int
    auth_drops: int
    replay_drops: int
    stale_drops: int


class Tap:
    """A man-in-the-middle between the host and the emulated device: forwards both ways,
    records every datagram, can hold back the host's datagrams that `hold` selects and
    inject any datagram towards the device. It has no key."""

    def __init__(self, device_port: int) -> None:
        self.device = ("127.0.0.1", device_port)
        self.front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # faces the host
        self.front.bind(("127.0.0.1", 0))
        self.port = int(self.front.getsockname()[1])
        self.back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # faces the device
        self.back.bind(("127.0.0.1", 0))
        self.host: tuple[str, int] | None = None
        self.to_device: list[bytes] = []
        self.to_host: list[bytes] = []
        self.samples: list[WireSample] = []
        self.held: list[bytes] = []
        self.hold: Callable[[bytes], bool] = lambda data: False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="tap", daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.front, self.back], [], [], 0.05)
            for sock in ready:
                data, addr = sock.recvfrom(4096)
                with self._lock:
                    if sock is self.front:
                        self.host = (str(addr[0]), int(addr[1]))
                        self.to_device.append(data)
                        if self.hold(data):
                            self.held.append(data)
                            continue
                        self.back.sendto(data, self.device)
                    else:
                        self.to_host.append(data)
                        if len(data) >= 92 and data[3] == SAMPLE:
                            t_us, seq, status = struct.unpack_from("<QII", data, 8)
                            drops = struct.unpack_from("<III", data, 32)
                            self.samples.append(WireSample(t_us, seq, status, *drops))
                        if self.host is not None:
                            self.front.sendto(data, self.host)

    def inject(self, data: bytes) -> None:
        """Send a datagram to the device from the tap (the host's address, to it)."""
        self.back.sendto(data, self.device)

    def latest(self) -> WireSample | None:
        with self._lock:
            return self.samples[-1] if self.samples else None

    def samples_since(self, index: int) -> list[WireSample]:
        with self._lock:
            return list(self.samples[index:])

    def __enter__(self) -> Tap:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2)
        self.front.close()
        self.back.close()


class Host:
    """`UdpDevice` driven from its own thread as the worker would: one command per
    sample, locking what `locks` says (left, right)."""

    def __init__(self, device: UdpDevice) -> None:
        self.device = device
        self.locks = (False, False)
        self.lock_once = False  # lock left on the next command only, then release
        self.samples: list[Sample] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="host", daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            sample = self.device.read(0.2)
            if sample is None:
                continue
            self.samples.append(sample)
            left, right = self.locks
            if self.lock_once:
                left, self.lock_once = True, False
            self.device.send(LockCommand(seq=sample.seq, lock_left=left, lock_right=right))

    def __enter__(self) -> Host:
        self.device.open()
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)
        self.device.close()


@contextmanager
def linked(emulator: Emulator) -> Iterator[tuple[Tap, Host]]:
    """A host joined to the emulated device through a tap, its first samples arrived."""
    with Tap(emulator.port) as tap, \
            Host(UdpDevice("127.0.0.1", tap.port, key=emulator.key)) as host:
        wait_for(lambda: len(host.samples) >= 5, 20, "the first samples of the emulated device")
        yield tap, host


def wait_samples(tap: Tap, n: int, what: str) -> None:
    """Wait for `n` more samples through the tap (the device's own pace)."""
    start = len(tap.samples_since(0))
    wait_for(lambda: len(tap.samples_since(0)) >= start + n, 20, what)


def inject_counted(tap: Tap, data: bytes, counter: Callable[[WireSample], int],
                   what: str) -> None:
    """Send `data` to the device and wait until the device's `counter` (read off its
    samples) has counted it. If 20 samples pass without, it is sent again: after an
    emulator stall the device may receive a burst larger than its tag-check budget per
    period and drop part of it unread (`flood`, which samples do not report)."""
    latest = tap.latest()
    assert latest is not None
    before = counter(latest)
    for _ in range(5):
        tap.inject(data)
        start = len(tap.samples_since(0))

        def settled(start: int = start) -> bool:
            now = tap.latest()
            return now is not None and (counter(now) > before
                                        or len(tap.samples_since(0)) >= start + 20)

        wait_for(settled, 20, f"the device counting {what}")
        now = tap.latest()
        if now is not None and counter(now) > before:
            return
    raise AssertionError(f"the device never counted {what}")


def energised(samples: list[WireSample]) -> list[int]:
    return [s.seq for s in samples if s.status & SOLENOIDS]


def test_joins_streams_and_energises_on_command(emulator: Emulator) -> None:
    """The protocol exchange with the firmware: HELLO, CHALLENGE (with the emulated
    board's identity), JOIN, then samples, every datagram of the device authentic; a
    lock command energises the left output as the samples report, a release clears it."""
    key = emulator.key
    with linked(emulator) as (tap, host):
        identity = host.device.identity
        assert identity is not None
        assert identity.firmware == FIRMWARE
        assert identity.key_id == key_id(key)
        assert identity.unique_id == simulated_unique_id(key).hex()
        first = host.samples[0]
        assert first.counts == (3100, 3105, 12900, 12890)
        assert not first.status & Status.ENCODER_FAULT
        assert first.status & Status.WATCHDOG_RELEASED  # released until a command
        assert tap.to_device[0][3] == HELLO
        challenge = next(d for d in tap.to_host if d[3] == CHALLENGE)
        join = next(d for d in tap.to_device if d[3] == JOIN)
        assert len(challenge) == 112
        assert join[16:32] == challenge[16:32]  # the JOIN answers the device's challenge
        assert challenge[32:48] == simulated_unique_id(key)
        assert challenge[48:64] == FIRMWARE.encode().ljust(16, b"\0")
        for data in tap.to_host:
            assert hmac.compare_digest(
                data[-TAG:], hmac.new(key, data[:-TAG], hashlib.sha256).digest())
        assert {len(d) for d in tap.to_host if d[3] == SAMPLE} == {92}

        host.locks = (True, False)
        wait_for(lambda: any(s.status & Status.SOLENOID_LEFT for s in host.samples[-5:]),
                 20, "a sample reporting the left solenoid energised")
        assert not any(s.status & Status.SOLENOID_RIGHT for s in host.samples)
        host.locks = (False, False)
        wait_for(lambda: all(not s.status & SOLENOIDS for s in host.samples[-5:]),
                 20, "samples reporting both solenoids released")
        assert host.device.link_counters().get("device_auth", 0) == 0


def test_forged_commands_never_energise(emulator: Emulator) -> None:
    """COMMANDs with their lock bits set and the tag of the original, or tagged with
    another key: dropped for the tag, counted, nothing energised."""
    with linked(emulator) as (tap, _host):
        wait_samples(tap, 3, "samples before the forgery")
        start = len(tap.samples_since(0))
        base = tap.latest()
        assert base is not None
        real = next(d for d in reversed(tap.to_device) if d[3] == COMMAND)
        other_key = bytes(32)
        forged = []
        for i in range(10):
            body = bytearray(real[:-TAG])
            body[16] = 3  # lock both
            body[8:12] = struct.pack("<I", (struct.unpack_from("<I", real, 8)[0] + 1000 + i))
            tag = (real[-TAG:] if i % 2 == 0
                   else hmac.new(other_key, bytes(body), hashlib.sha256).digest())
            forged.append(bytes(body) + tag)
        for data in forged:
            inject_counted(tap, data, lambda s: s.auth_drops, "a forged command")
        wait_samples(tap, 3, "samples after the forgeries")
        after = tap.samples_since(start)
        assert energised(after) == []
        assert after[-1].auth_drops == base.auth_drops + len(forged)


def test_replayed_lock_commands_never_energise(emulator: Emulator) -> None:
    """The host's real lock COMMANDs, recorded and sent again after it released:
    dropped as replays (their host_seq is not later than the last applied)."""
    with linked(emulator) as (tap, host):
        host.locks = (True, True)
        wait_for(lambda: len(energised(tap.samples_since(0))) >= 10,
                 20, "the host's lock applied for 10 samples")
        host.locks = (False, False)
        wait_for(lambda: (s := tap.latest()) is not None and not s.status & SOLENOIDS,
                 20, "the release applied")
        recorded = [d for d in tap.to_device if d[3] == COMMAND and d[16] != 0][:20]
        assert recorded
        base = tap.latest()
        assert base is not None
        start = len(tap.samples_since(0))
        for data in recorded:
            inject_counted(tap, data, lambda s: s.replay_drops, "a replayed lock command")
        wait_samples(tap, 3, "samples after the replay")
        after = tap.samples_since(start)
        assert energised(after) == []
        assert after[-1].replay_drops == base.replay_drops + len(recorded)


def test_command_held_back_is_dropped_as_stale(emulator: Emulator) -> None:
    """A real lock COMMAND held back until the device's clock is 150 ms past the sample
    it answers, no later command delivered meanwhile: dropped as stale, not applied."""
    with linked(emulator) as (tap, host):
        base = tap.latest()
        assert base is not None
        start = len(tap.samples_since(0))
        tap.hold = lambda data: data[3] == COMMAND
        host.lock_once = True
        def held_lock() -> bytes | None:
            return next((d for d in list(tap.held) if d[16] != 0), None)

        wait_for(held_lock, 20, "the host's lock command, held by the tap")
        lock = held_lock()
        assert lock is not None
        echo = struct.unpack_from("<I", lock, 12)[0]

        def echoed_sample() -> WireSample | None:
            # From the session's first sample: a host that reads late (a loaded machine)
            # may answer a sample the tap passed on before `start` was taken.
            return next((s for s in tap.samples_since(0) if s.seq == echo), None)

        wait_for(echoed_sample, 20, "the sample the lock command answers")
        echoed = echoed_sample()
        assert echoed is not None
        wait_for(lambda: (s := tap.latest()) is not None and s.t_us >= echoed.t_us + 150_000,
                 20, "the device's clock 150 ms past the echoed sample")
        inject_counted(tap, lock, lambda s: s.stale_drops, "the late command as stale")
        tap.hold = lambda data: False
        wait_samples(tap, 5, "samples after the late command")
        after = tap.samples_since(start)
        assert energised(after) == []
        assert after[-1].stale_drops == base.stale_drops + 1


def test_replayed_join_changes_nothing(emulator: Emulator) -> None:
    """The host's own JOIN sent again (twice) while its session runs: its challenge is
    spent, so it is dropped as a replay; the stream goes on to the host, unchanged."""
    with linked(emulator) as (tap, host):
        join = next(d for d in tap.to_device if d[3] == JOIN)
        base = tap.latest()
        assert base is not None
        start = len(tap.samples_since(0))
        host_samples = len(host.samples)
        inject_counted(tap, join, lambda s: s.replay_drops, "a replayed JOIN")
        inject_counted(tap, join, lambda s: s.replay_drops, "the JOIN replayed again")
        wait_samples(tap, 5, "samples after the replayed JOIN")
        after = tap.samples_since(start)
        assert energised(after) == []
        assert after[-1].replay_drops == base.replay_drops + 2
        seqs = [s.seq for s in after]
        assert seqs == sorted(seqs) and seqs[0] > base.seq  # the stream was not restarted
        wait_for(lambda: len(host.samples) > host_samples + 3, 20,
                 "the host still receiving samples")
        assert host.device.link_counters().get("device_restarts", 0) == 0
