"""Fixtures of the fault-injection suite."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import pytest

from tests import c_device


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


@pytest.fixture(params=c_device.IMPLEMENTATIONS)
def device_implementation(request: pytest.FixtureRequest) -> str:
    """Each device-facing fault test runs against the Python reference device and the
    C firmware core (firmware/ports/linux-sim), so the two cannot drift apart."""
    implementation: str = request.param
    if implementation == "c":
        c_device.build()
    return implementation
