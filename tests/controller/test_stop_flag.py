"""The signal-safe stop flag: set from a real signal handler, re-entered."""

from __future__ import annotations

import os
import signal
from types import FrameType

from controller.stop_flag import SignalSafeFlag


def test_set_from_a_handler_while_the_main_thread_sets_it() -> None:
    """Signals arriving while the main thread is inside `set()` still set the flag and
    return (an `Event` here can wait for its own thread's lock)."""
    flag = SignalSafeFlag()
    calls = 0

    def handler(_signum: int, _frame: FrameType | None) -> None:
        nonlocal calls
        calls += 1
        flag.set()

    previous = signal.signal(signal.SIGUSR1, handler)
    try:
        assert not flag.is_set()
        for _ in range(200):
            os.kill(os.getpid(), signal.SIGUSR1)
            flag.set()
    finally:
        signal.signal(signal.SIGUSR1, previous)
    assert flag.is_set() and calls == 200
