"""Fixtures of the fault-injection suite."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import pytest


@pytest.fixture
def busy_cores() -> Iterator[int]:
    """Every core busy with a spinning process for the duration of the test (races and
    timeouts show up under load, not on an idle machine); yields how many."""
    n = os.cpu_count() or 2
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
                for _ in range(n)]
    try:
        yield n
    finally:
        for p in spinners:
            p.kill()
        for p in spinners:
            p.wait(10)
