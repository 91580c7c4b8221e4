"""Device processes without an interpreter start each: forked from one process that has
already imported the simulated exoskeleton and loaded its compiled kernels.

A Python device (`python -m controller.sim.device_server`) or the C device's simulated
wearer (`python -m controller.sim.plant_bridge`, its child) spends about 1.3 s of CPU
importing numpy, numba and scipy and loading the kernels before its first sample, and
the fault tests start about 25 of them. Here one process per test module, the zygote,
pays that once; each device is then a `fork()` of it that runs the same entry point
(`main(argv)`) with the same arguments, standard streams and working folder, as a
process of its own: its own address space, UDP socket, signals and exit status. What
the tests inject (datagrams, signals, kills) reaches it exactly as before.

- `Zygote.spawn(module, args)`: a Python entry point as a forked process; returns a
  `ZygoteProcess` (the parts of `subprocess.Popen` the tests use: `pid`, `poll`,
  `wait`, `send_signal`, `terminate`, `kill`, `communicate`, `returncode`).
- `Zygote.launcher`: an executable to hand the C device as `--python`: it passes its
  standard streams (the C device's pipes) and arguments to the zygote, forwards signals
  to the forked wearer and exits with its status, so the C device starts, feeds, stops
  and reaps its wearer as it would a fresh interpreter.

The zygote reaps its children (their CPU time is counted in its own), and is stopped
and reaped by `close()` at the end of the module that started it, so the CPU of every
device lands in that module's figures (`EXOSTUDY_TEST_CPU`). It stays single-threaded:
forking a process with threads could leave a lock held in the child.

    python -m tests.faults.zygote SOCKET    (started by `Zygote`, not by hand)
"""

from __future__ import annotations

import array
import importlib
import json
import os
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
#: The modules a forked process may run (`main(argv)` of each).
ENTRY_POINTS = ("controller.sim.device_server", "controller.sim.plant_bridge")
#: Where the functions a forked process may call (`Zygote.call`) live.
CALLABLE_PACKAGE = "tests.faults."
#: What the zygote writes on its standard output once it accepts requests.
READY = "zygote ready"
#: How long its imports may take (about 2 s on an idle machine).
START_TIMEOUT_S = 120.0
#: The launcher handed to the C device as `--python` (the placeholders are filled in).
LAUNCHER = '''#!{python} -IS
"""`python -m MODULE ARGS` for the C device, forked from the zygote at {socket}."""
import array, json, os, signal, socket, sys
if len(sys.argv) < 3 or sys.argv[1] != "-m":
    sys.exit("zygote launcher: expected -m MODULE ARGS")
conn = socket.socket(socket.AF_UNIX)
conn.connect({socket!r})
request = json.dumps({{"module": sys.argv[2], "args": sys.argv[3:],
                      "cwd": os.getcwd()}}).encode()
conn.sendmsg([request], [(socket.SOL_SOCKET, socket.SCM_RIGHTS,
                          array.array("i", [0, 1, 2]).tobytes())])
# The forked process holds the device's pipes now: it alone sees their end.
null = os.open(os.devnull, os.O_RDWR)
os.dup2(null, 0)
os.dup2(null, 1)
answers = conn.makefile("r")
pid = int(answers.readline())
for number in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
    signal.signal(number, lambda n, _f: os.kill(pid, n))
status = answers.readline()
code = int(status) if status.strip() else 1
os._exit(code if code >= 0 else 128 - code)
'''


# -- the zygote process -----------------------------------------------------------------


def _preload() -> None:
    """Import every entry point and pay the kernels' loading once, on a throwaway model."""
    for name in ENTRY_POINTS:
        importlib.import_module(name)
    from controller.sim.exoskeleton import SimulatedExoskeleton

    model = SimulatedExoskeleton(seed=0, script="squat-sequence", loop=False)
    model.tick(None)


def _receive(conn: socket.socket) -> tuple[dict[str, Any], list[int]]:
    """One request and the three descriptors sent with it."""
    fds = array.array("i")
    data, ancillary, _, _ = conn.recvmsg(65536, socket.CMSG_SPACE(3 * fds.itemsize))
    for level, kind, payload in ancillary:
        if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
            fds.frombytes(payload[: len(payload) - len(payload) % fds.itemsize])
    request: dict[str, Any] = json.loads(data)
    return request, list(fds)


def _run_child(request: dict[str, Any], fds: list[int], keep_closed: list[int]) -> None:
    """In the forked process: become `python -m MODULE ARGS` with the sent streams."""
    code = 1
    try:
        signal.set_wakeup_fd(-1)
        for fd in keep_closed:
            os.close(fd)
        for number in (signal.SIGCHLD, signal.SIGTERM, signal.SIGHUP):
            signal.signal(number, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
        for fd in set(fds) - {0, 1, 2}:
            os.close(fd)
        os.chdir(request["cwd"])
        if "call" in request:  # a device target of the fault tests: target(*args)
            module, _, name = request["call"].partition(":")
            if not module.startswith(CALLABLE_PACKAGE):
                raise SystemExit(f"zygote: {module} is not a module of {CALLABLE_PACKAGE}")
            sys.argv = [module]
            getattr(importlib.import_module(module), name)(*request["args"])
            code = 0
        else:
            module = request["module"]
            if module not in ENTRY_POINTS:
                raise SystemExit(f"zygote: {module} is not an entry point it runs")
            sys.argv = [module, *request["args"]]
            code = int(importlib.import_module(module).main(request["args"]) or 0)
    except SystemExit as exc:
        if isinstance(exc.code, int) or exc.code is None:
            code = int(exc.code or 0)
        else:
            print(exc.code, file=sys.stderr)
            code = 1
    except KeyboardInterrupt:
        code = 128 + signal.SIGINT
    except BaseException:
        traceback.print_exc()
        code = 1
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code)


def serve(path: str) -> None:
    """Accept requests on `path` until standard input ends (the test process closed it
    or died), then kill what still runs, reap it and exit."""
    _preload()
    listener = socket.socket(socket.AF_UNIX)
    listener.bind(path)
    listener.listen(16)
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_r, False)
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    signal.signal(signal.SIGCHLD, lambda _n, _f: None)
    waiting: dict[int, socket.socket] = {}  # pid -> the requester, told its exit status
    print(READY, flush=True)

    def reap() -> None:
        while waiting:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            conn = waiting.pop(pid, None)
            if conn is not None:
                try:
                    conn.sendall(f"{os.waitstatus_to_exitcode(status)}\n".encode())
                except OSError:
                    pass
                conn.close()

    while True:
        try:
            ready, _, _ = select.select([listener, wake_r, sys.stdin], [], [], 1.0)
        except InterruptedError:
            continue
        if wake_r in ready:
            try:
                os.read(wake_r, 4096)
            except BlockingIOError:
                pass
        reap()
        if sys.stdin in ready and not os.read(sys.stdin.fileno(), 4096):
            break
        if listener in ready:
            conn, _ = listener.accept()
            try:
                request, fds = _receive(conn)
            except (OSError, ValueError):
                conn.close()
                continue
            if len(fds) != 3:
                for fd in fds:
                    os.close(fd)
                conn.close()
                continue
            open_fds = [listener.fileno(), wake_r, wake_w, *(c.fileno() for c in waiting.values()),
                        conn.fileno()]
            pid = os.fork()
            if pid == 0:
                _run_child(request, fds, open_fds)
            for fd in fds:
                os.close(fd)
            waiting[pid] = conn
            conn.sendall(f"{pid}\n".encode())
            reap()
    for pid in list(waiting):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    while waiting:
        try:
            pid, _ = os.waitpid(-1, 0)
        except ChildProcessError:
            break
        waiting.pop(pid, None)


# -- the test process's side ------------------------------------------------------------


class ZygoteProcess:
    """A process forked by the zygote, seen as `subprocess.Popen` (text mode): not this
    process's child, so its exit status comes from the zygote, which reaps it."""

    def __init__(self, conn: socket.socket, out: Path, err: Path) -> None:
        self._conn = conn
        self._buffer = b""
        line = self._line(START_TIMEOUT_S)
        if not line:
            conn.close()
            raise AssertionError("the device zygote did not fork (is it still running?)")
        self.pid = int(line)
        self._out, self._err = out, err
        self.returncode: int | None = None

    def _line(self, timeout: float | None) -> bytes | None:
        """The zygote's next line; None if none came within `timeout` s, b"" at its end."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while b"\n" not in self._buffer:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not select.select([self._conn], [], [], left)[0]:
                return None
            chunk = self._conn.recv(4096)
            if not chunk:
                return b""
            self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line

    def _status(self, timeout: float | None) -> int | None:
        if self.returncode is None:
            line = self._line(timeout)
            if line is None:
                return None
            # No status line: the zygote itself is gone (it kills its children first).
            self.returncode = int(line) if line.strip() else -int(signal.SIGKILL)
            self._conn.close()
        return self.returncode

    def poll(self) -> int | None:
        """The exit status, or None while it runs."""
        return self._status(0.0)

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the exit status (`subprocess.TimeoutExpired` after `timeout` s)."""
        code = self._status(timeout)
        if code is None:
            raise subprocess.TimeoutExpired(f"zygote child {self.pid}", timeout or 0.0)
        return code

    def send_signal(self, number: int) -> None:
        """Signal it if it still runs (its pid is not reused before the zygote has
        reaped it and told us)."""
        if self.poll() is None:
            try:
                os.kill(self.pid, number)
            except ProcessLookupError:
                pass

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        """Wait for the end; what it wrote on its standard output and error."""
        self.wait(timeout)
        return (self._out.read_text(errors="replace"), self._err.read_text(errors="replace"))


class Zygote:
    """The zygote process for this module's devices (started by `start`)."""

    def __init__(self) -> None:
        self._folder = Path(tempfile.mkdtemp(prefix="exostudy-zygote-"))
        self.socket = str(self._folder / "socket")
        self.launcher = self._folder / "python"
        self.launcher.write_text(LAUNCHER.format(python=sys.executable, socket=self.socket))
        self.launcher.chmod(0o700)
        self._count = 0
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.faults.zygote", self.socket],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, cwd=ROOT,
            env={**os.environ, "PYTHONPATH": str(ROOT)}, text=True)
        assert self.proc.stdout is not None
        started = select.select([self.proc.stdout], [], [], START_TIMEOUT_S)[0]
        line = self.proc.stdout.readline().strip() if started else ""
        if line != READY:
            self.close()
            raise AssertionError(f"the device zygote did not start (it said {line!r})")

    def spawn(self, module: str, args: list[str], cwd: Path = ROOT) -> ZygoteProcess:
        """`python -m MODULE ARGS` forked from the zygote, its standard input empty and
        its output kept for `communicate`."""
        return self._fork({"module": module, "args": args, "cwd": str(cwd)})

    def call(self, target: Callable[..., object], *args: Any) -> ZygoteProcess:
        """`target(*args)` in a process forked from the zygote: a module-level function
        of tests/faults (imported there by name), its arguments plain JSON values."""
        name = f"{target.__module__}:{target.__qualname__}"
        return self._fork({"call": name, "args": list(args), "cwd": str(ROOT)})

    def _fork(self, request: dict[str, Any]) -> ZygoteProcess:
        self._count += 1
        out = self._folder / f"{self._count}.out"
        err = self._folder / f"{self._count}.err"
        conn = socket.socket(socket.AF_UNIX)
        conn.connect(self.socket)
        with open(os.devnull, "rb") as stdin, open(out, "wb") as o, open(err, "wb") as e:
            fds = array.array("i", [stdin.fileno(), o.fileno(), e.fileno()])
            conn.sendmsg([json.dumps(request).encode()],
                          [(socket.SOL_SOCKET, socket.SCM_RIGHTS, fds.tobytes())])
            return ZygoteProcess(conn, out, err)

    def close(self) -> None:
        """End of its input: it kills what still runs and exits; reaped here."""
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        try:
            self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        for path in self._folder.iterdir():
            path.unlink()
        self._folder.rmdir()


_current: Zygote | None = None
_active = False


def active() -> bool:
    """Whether a module has asked for a zygote (`per_module`): outside one, there is
    nobody to stop it."""
    return _active


def current() -> Zygote:
    """The zygote of the running module (started on first use)."""
    global _current
    if not _active:
        raise RuntimeError("no zygote outside `per_module()` (tests/faults/conftest.py)")
    if _current is None:
        _current = Zygote()
    return _current


@contextmanager
def per_module() -> Iterator[None]:
    """A module's devices fork from one zygote, stopped (and reaped) when it ends."""
    global _active, _current
    _active = True
    try:
        yield
    finally:
        _active = False
        if _current is not None:
            _current.close()
            _current = None


if __name__ == "__main__":
    serve(sys.argv[1])
