"""Waiting in tests: poll a condition until it holds, with a deadline, never a fixed sleep.

A fixed sleep is either too short on a busy machine (the test flakes) or too long on a
quiet one (the suite crawls); polling ends as soon as the thing happened and fails with
a message naming what never did. Free ports live here too, since every test that starts
a real server or device needs one right before it waits for it.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def wait_for(cond: Callable[[], T], timeout: float, what: str, poll: float = 0.02) -> T:
    """Poll `cond` until it returns something truthy, and return that; after `timeout`
    seconds fail with an `AssertionError` naming `what`."""
    deadline = time.monotonic() + timeout
    while True:
        value = cond()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(poll)


def free_tcp_port() -> int:
    """A TCP port nobody listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def free_udp_port() -> int:
    """A UDP port nobody has bound right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])
