"""The tick-time map and the lock edges of `backend.lab.lsl_outlets`, without the network
(outlets off: the same arithmetic on the monotonic clock)."""

from __future__ import annotations

import json
import time

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from backend.lab.lsl_outlets import LabOutlets
from backend.worker.messages import TickBatch
from controller.tick_record import TickRecord


class MarkerCapture(LabOutlets):
    """Keeps the markers it would send."""

    def __init__(self) -> None:
        super().__init__(enabled=False)
        self.sent: list[tuple[dict[str, object], float]] = []

    def push_marker(self, text: str, lsl_time: float) -> None:
        self.sent.append((json.loads(text), lsl_time))


def _batch(token: int, start: int, locks: list[tuple[bool, bool]], t_host0: float
           ) -> TickBatch:
    return TickBatch.from_records(token, tuple(
        TickRecord(seq=start + i, t=(start + i) / 100, t_host=t_host0 + i / 100,
                   lock_left=left, lock_right=right)
        for i, (left, right) in enumerate(locks)))


def test_lock_edges_per_side_are_stamped_with_their_tick() -> None:
    out = MarkerCapture()
    out.run_started(7, 42)
    t0 = time.time()
    pattern = [(False, False)] * 3 + [(True, False)] * 2 + [(True, True)] + [(False, True)]
    # Split across two batches: an edge at the batch boundary is still seen once.
    out.on_ticks(_batch(7, 0, pattern[:4], t0))
    out.on_ticks(_batch(7, 4, pattern[4:], t0 + 0.04))
    events = [(m["event"], m["side"], m["t"], m["run_id"]) for m, _ in out.sent]
    assert events == [("lock", "left", 0.03, 42), ("lock", "right", 0.05, 42),
                      ("release", "left", 0.06, 42)]
    offset = time.monotonic() - time.time()
    for (m, stamp) in out.sent:
        read = t0 + float(m["t"])  # type: ignore[arg-type]
        assert abs(stamp - (read + offset)) < 1e-3
    latest = out.latest()
    assert latest is not None and latest.run_id == 42 and latest.t == 0.06


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 0.05), min_size=1, max_size=300),
       st.floats(-0.5, 4.0))
def test_tick_at_finds_the_nearest_tick(gaps: list[float], where: float) -> None:
    out = LabOutlets(enabled=False)
    out.run_started(1, 5)
    hosts = 1.7e9 + np.cumsum(gaps)
    records = tuple(TickRecord(seq=i, t=float(i), t_host=float(h))
                    for i, h in enumerate(hosts))
    out.on_ticks(TickBatch.from_records(1, records))
    stamps = np.array(out._map_lsl)
    target = float(stamps[0] + where)
    found = out.tick_at(target)
    nearest = int(np.argmin(np.abs(stamps - target)))
    if abs(stamps[nearest] - target) > 1.0:
        assert found is None
    else:
        assert found is not None and found.run_id == 5
        # The same distance as numpy's nearest (ties may pick either neighbour).
        assert abs(found.lsl_time - target) == abs(stamps[nearest] - target)
        # ... and the tick time of a tick with that stamp (read times can coincide).
        assert found.t in np.flatnonzero(stamps == found.lsl_time).astype(float)
