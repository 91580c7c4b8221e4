"""What the health endpoint says about the simulated wearer's pace: whether a timed run
is over, and how fast the worker ticks now (the tests of timed simulated runs, which
end the speed-up with them)."""

from __future__ import annotations

import time

from fastapi.testclient import TestClient


def past_run(client: TestClient, run_id: int, ticks: int) -> bool:
    """Whether the worker has ended run `run_id` and reported at least `ticks` ticks of
    its wearer (a status from after the run's end, not one sent just before it)."""
    health = client.get("/api/health").json()
    return bool(health["database"]["current_run_id"] != run_id
                and health["worker"]["ticks"] >= ticks)


def ticks_per_second(client: TestClient, seconds: float = 1.0) -> float:
    """The worker's ticks per second of wall time over about `seconds`: an upper bound
    on the simulator's speed (a loaded machine only makes it lower)."""
    n0, t0 = client.get("/api/health").json()["worker"]["ticks"], time.monotonic()
    time.sleep(seconds)
    n1, t1 = client.get("/api/health").json()["worker"]["ticks"], time.monotonic()
    return float(n1 - n0) / (t1 - t0)
