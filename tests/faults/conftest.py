"""Fixtures of the fault-injection suite."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests import c_device
from tests.faults import zygote
from tests.faults.busy import Spinners


@pytest.fixture
def spinners() -> Iterator[Spinners]:
    """Every core busy from the moment the test calls `start()` to its end."""
    busy = Spinners()
    try:
        yield busy
    finally:
        busy.stop()


@pytest.fixture
def busy_cores(spinners: Spinners) -> int:
    """Every core busy with a spinning process for the duration of the test; how many."""
    return spinners.start()


@pytest.fixture(params=c_device.IMPLEMENTATIONS)
def device_implementation(request: pytest.FixtureRequest) -> str:
    """Each device-facing fault test runs against the Python reference device and the
    C firmware core (firmware/ports/linux-sim), so the two cannot drift apart."""
    implementation: str = request.param
    if implementation == "c":
        c_device.build()
    return implementation


@pytest.fixture(scope="module", autouse=True)
def device_zygote() -> Iterator[None]:
    """The module's device processes fork from one zygote (tests/faults/zygote.py),
    started on first use and stopped, with whatever it still runs, when the module
    ends: the CPU of its devices is counted in the module's."""
    with zygote.per_module():
        yield
