"""The simulated exoskeleton as a child process of the server, which it may never outlive.

An orphaned simulator keeps the device's UDP port and goes on playing its old script, so
the next server's simulator cannot bind and the worker talks to the orphan. Three
measures prevent it:

- the child asks the kernel for SIGTERM when its parent dies (`PR_SET_PDEATHSIG`, set
  by the child itself at start: see `die_with_parent`), so a server killed with
  SIGKILL takes its simulator along;
- the server writes the child's pid to a file under `var/`; a restarted server kills a
  simulator still named there (checked by its command line, so a reused pid is never
  hit) before it binds the port again;
- a start counts only once the child holds the port: a child that exits first (the port
  taken by someone else, a bad script) is an error with the child's own message.

The child is the Python reference device (`exostudy device-sim`) or, with setting
`device_implementation = "c"`, the C firmware core built for Linux
(`firmware/build/exostudy-device`, same arguments): both do the same three things.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

#: Environment variable that tells a spawned simulator which pid must stay its parent.
PARENT_ENV = "EXOSTUDY_PARENT_PID"
#: linux/prctl.h
PR_SET_PDEATHSIG = 1
#: How long a simulator may take to bind its port (interpreter start and imports take
#: about 1 s on an idle machine; 20 s leaves room for a machine with both cores busy).
START_TIMEOUT_S = 20.0


#: The C device's executable (firmware/ports/linux-sim), as `make install` builds it.
C_DEVICE_NAME = "exostudy-device"
#: Environment variable naming the C device's executable explicitly (another build).
C_DEVICE_ENV = "EXOSTUDY_DEVICE_BINARY"
_CHECKOUT = Path(__file__).resolve().parents[2]
C_DEVICE_BUILD = _CHECKOUT / "firmware" / "build" / C_DEVICE_NAME


class DeviceStartError(RuntimeError):
    """The simulated device could not be started; the message says why."""


def c_device_binary() -> Path:
    """The C device's executable: `EXOSTUDY_DEVICE_BINARY` if set, else the checkout's
    build (firmware/build/exostudy-device), else one on PATH. Raises DeviceStartError
    saying how to build it when there is none."""
    explicit = os.environ.get(C_DEVICE_ENV)
    if explicit:
        path = Path(explicit)
        if path.is_file() and os.access(path, os.X_OK):
            return path
        raise DeviceStartError(f"{C_DEVICE_ENV}={explicit}: no executable there")
    if C_DEVICE_BUILD.is_file() and os.access(C_DEVICE_BUILD, os.X_OK):
        return C_DEVICE_BUILD
    found = shutil.which(C_DEVICE_NAME)
    if found:
        return Path(found)
    raise DeviceStartError(
        f"the C device is not built ({C_DEVICE_BUILD} is missing): run "
        f"`make -C {_CHECKOUT / 'firmware' / 'ports' / 'linux-sim'}` (or `make install`), "
        f"or set device_implementation to 'python'")


def device_command(args: list[str], implementation: str = "python") -> list[str]:
    """The command line of a device simulator with `exostudy device-sim` arguments:
    the Python reference device, or the C device running its simulated wearer on this
    interpreter (`--python`)."""
    if implementation == "c":
        return [str(c_device_binary()), *args, "--python", sys.executable]
    if implementation != "python":
        raise DeviceStartError(f"device implementation {implementation!r}: expected "
                               "'python' or 'c'")
    return [sys.executable, "-m", "backend.cli", "device-sim", *args]


def die_with_parent() -> None:
    """In a spawned simulator: get SIGTERM when the server dies; exit now if it already
    has. Does nothing outside a server-spawned process (no `PARENT_ENV`)."""
    expected = os.environ.get(PARENT_ENV)
    if not expected:
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):
        pass  # not Linux: the pid file still lets the next server reclaim the port
    # The parent may have died between fork and prctl: then nobody will signal us.
    if os.getppid() != int(expected):
        raise SystemExit(4)


def udp_port_bound(port: int) -> bool:
    """Whether any local UDP socket (IPv4 or IPv6) is bound to `port` (from /proc)."""
    hex_port = f":{port:04X}"
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) > 1 and fields[1].endswith(hex_port):
                return True
    return False


def _is_simulator(pid: int, port: int) -> bool:
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return False
    is_device = b"device-sim" in argv or Path(os.fsdecode(argv[0])).name == C_DEVICE_NAME
    return is_device and str(port).encode() in argv


def reclaim(pid_file: Path, port: int, timeout: float = 3.0) -> int | None:
    """Stop a simulator left by an earlier server on `port`; returns its pid if one was
    stopped. Only a process whose command line is a device simulator on that port is
    touched."""
    try:
        pid = int(pid_file.read_text().strip())
    except (OSError, ValueError):
        return None
    if not _is_simulator(pid, port):
        pid_file.unlink(missing_ok=True)
        return None
    for sig, wait_s in ((signal.SIGTERM, timeout), (signal.SIGKILL, timeout)):
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            break
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline and _is_simulator(pid, port):
            time.sleep(0.02)
        if not _is_simulator(pid, port):
            break
    pid_file.unlink(missing_ok=True)
    return pid


def spawn(args: list[str], port: int, pid_file: Path, log_file: Path,
          implementation: str = "python") -> subprocess.Popen[bytes]:
    """Start `exostudy device-sim ARGS` (or the C device with the same ARGS) and return
    once it holds `port`.

    Raises DeviceStartError if the port is taken by another process, the C device is
    not built, or the child exits (or does not bind) first; the child's last output is
    in the message."""
    command = device_command(args, implementation)
    if udp_port_bound(port):
        raise DeviceStartError(f"UDP port {port} is in use by another process; stop it or "
                               "set EXOSTUDY_DEVICE_ADDRESS to a free port")
    pid_file.parent.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, **{PARENT_ENV: str(os.getpid())})
    with open(log_file, "wb") as log:
        proc = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=env)
    pid_file.write_text(f"{proc.pid}\n")
    deadline = time.monotonic() + START_TIMEOUT_S
    while True:
        code = proc.poll()
        if code is not None:
            pid_file.unlink(missing_ok=True)
            raise DeviceStartError(f"the simulated device exited with code {code}: "
                                   f"{_tail(log_file)}")
        if udp_port_bound(port):
            return proc
        if time.monotonic() > deadline:
            stop(proc, pid_file)
            raise DeviceStartError(f"the simulated device did not bind UDP port {port} within "
                                   f"{START_TIMEOUT_S:g} s")
        time.sleep(0.02)


def stop(proc: subprocess.Popen[bytes], pid_file: Path, timeout: float = 3.0) -> None:
    """Terminate the simulator (it releases the solenoids), kill it if it lingers."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout)
    try:
        if pid_file.read_text().strip() == str(proc.pid):
            pid_file.unlink()
    except OSError:
        pass


def _tail(path: Path, chars: int = 400) -> str:
    try:
        text = path.read_text(errors="replace").strip()
    except OSError:
        return "(no output)"
    return text[-chars:] or "(no output)"
