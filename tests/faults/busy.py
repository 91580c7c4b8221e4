"""Load for the fault tests: a spinning process on every core."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.polling import wait_for

#: CPU clock ticks (10 ms) a spinner has used once it is past the interpreter's start.
SPUN_TICKS = 5


class Spinners:
    """A spinning process on every core, started when the test says so (`start`) and
    stopped when it ends: races and timeouts show up under load, not on an idle machine.

    A test whose fault comes after a slow start (a server, a worker, a job's process)
    starts the load when the fault's phase begins: starting processes under two busy
    loops only makes them slower (tens of seconds), and how fast they start is not what
    such a test asserts (the start-up benchmark measures that)."""

    def __init__(self) -> None:
        self.n = os.cpu_count() or 2
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self) -> int:
        """Busy every core (once), returning when every spinner spins (more CPU time
        in /proc than an interpreter's start takes), so the load is on from here;
        returns how many."""
        if not self.procs:
            self.procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
                          for _ in range(self.n)]
            wait_for(lambda: all(_cpu_ticks(p.pid) > SPUN_TICKS for p in self.procs), 30,
                     "the spinners to spin")
        return self.n

    def stop(self) -> None:
        for p in self.procs:
            p.kill()
        for p in self.procs:
            p.wait(10)


def _cpu_ticks(pid: int) -> int:
    """User CPU time of `pid` so far, in clock ticks (/proc/PID/stat, field 14)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return 0
    return int(stat.rsplit(")", 1)[1].split()[11])
