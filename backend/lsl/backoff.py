"""How long an LSL inlet waits before it looks for its stream again.

After a resolve round that ended without a stream sooner than it should (liblsl refused
the query, or the network layer failed), and between reconnections: doubled each time
from 1 s, at most 30 s (an assumption: a restarted sender is back within seconds, and a
check every 30 s costs nothing). The marker inlets and the EMG inlets wait the same way.
"""

from __future__ import annotations

from collections.abc import Iterator

BACKOFF_FIRST_S = 1.0
BACKOFF_MAX_S = 30.0


def backoff_delays() -> Iterator[float]:
    """1, 2, 4, ... seconds, then `BACKOFF_MAX_S` for ever."""
    delay = BACKOFF_FIRST_S
    while True:
        yield delay
        delay = min(BACKOFF_MAX_S, delay * 2)
