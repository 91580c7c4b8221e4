"""A stop flag that a signal handler may set.

`threading.Event.set` takes a lock. A handler that calls it runs on the main thread
between two bytecodes, possibly while that thread is itself inside `Event.set` (or a
first handler is): it then waits for a lock its own thread holds, for good. An orphaned
device simulator hung that way with SIGTERM caught and never acted on. A plain
attribute needs no lock; reading it from another thread is safe under the GIL.
"""

from __future__ import annotations


class SignalSafeFlag:
    """`set()` from anywhere, signal handlers included; `is_set()` polls it."""

    def __init__(self) -> None:
        self.raised = False

    def set(self) -> None:
        self.raised = True

    def is_set(self) -> bool:
        return self.raised
