"""The C device (firmware/ports/linux-sim) for the tests that run both device
implementations: built once per session with the port's own Makefile (a no-op when
`make install` already built it), so a test never runs a stale binary."""

from __future__ import annotations

import subprocess
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PORT = ROOT / "firmware" / "ports" / "linux-sim"
BUILD = ROOT / "firmware" / "build"
#: The device implementations every cross-implementation test runs: the Python
#: reference device and the C firmware core on Linux.
IMPLEMENTATIONS = ("python", "c")


@lru_cache(maxsize=1)
def build() -> Path:
    """Build the C device and its vector tool; returns the build folder. Fails with
    make's own output (a compiler error is a test failure, not a skip)."""
    done = subprocess.run(["make", "-s", "-C", str(PORT)], capture_output=True, text=True,
                          timeout=600)
    if done.returncode != 0:
        raise AssertionError(f"building the C device failed:\n{done.stdout}\n{done.stderr}")
    return BUILD


def device_binary() -> Path:
    """firmware/build/exostudy-device, built."""
    return build() / "exostudy-device"


def vectors_binary() -> Path:
    """firmware/build/exostudy-device-vectors, built."""
    return build() / "exostudy-device-vectors"
