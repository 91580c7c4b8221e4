"""The experimenter's side of a virtual study: REST calls checked for the status they
must answer, and waits on the worker's progress (ticks, runs, jobs) that fail only when
progress stops. Every phase drives the server through it; it also holds what both
phases ask of the simulator (a participant's record, the length of a script)."""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import Any

from backend.analysis.virtual_study_config import STALL_S, VirtualStudyError
from backend.live.local_server import ApiClient, Response
from controller.device.base import SAMPLE_PERIOD_S
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import get_script, realise

#: Longest wait between two looks at the worker, so that a stall is noticed in time.
MAX_SLEEP_S = 2.0


def ok(r: Response, code: int = 200) -> Any:
    """The JSON of an answer with status `code`; else the step fails, naming the call."""
    if r.status_code != code:
        raise VirtualStudyError(f"{r.method} {r.path}: {r.status_code} {r.text[:500]}")
    return r.json()


def ok_text(r: Response) -> str:
    """The text of a 200 answer to a GET (a table)."""
    if r.status_code != 200:
        raise VirtualStudyError(f"GET {r.path}: {r.status_code} {r.text[:300]}")
    return r.text


def ok_bytes(r: Response) -> bytes:
    """The body of a 200 answer to a GET (a figure)."""
    if r.status_code != 200:
        raise VirtualStudyError(f"GET {r.path}: {r.status_code} {r.text[:300]}")
    return r.content


class Driver:
    """The experimenter's side: REST calls, and waiting on the device's ticks."""

    def __init__(self, client: ApiClient, speed: float, log: Callable[[str], None]) -> None:
        self.c = client
        self.speed = speed
        self.log = log

    def ticks(self) -> int:
        return int(ok(self.c.get("/api/health"))["worker"]["ticks"])

    def _poll_s(self) -> float:
        return min(0.25, max(0.02, 2.0 / self.speed))

    def _sleep_s(self, remaining_ticks: float) -> float:
        """How long to wait before the next look at the worker: the usual poll, or half
        the time the ticks still to come take at the requested speed while that is
        longer. Every look is a request the server answers (a few ms of CPU), and a
        trial at 30x took a hundred of them; halving keeps the look after the target as
        prompt as before (a simulation that catches up runs at most about twice the
        requested speed)."""
        ahead = 0.5 * max(remaining_ticks, 0.0) * SAMPLE_PERIOD_S / self.speed
        return min(max(self._poll_s(), ahead), MAX_SLEEP_S)

    def wait_ticks(self, target: int) -> None:
        """Until the worker has produced `target` ticks since the simulation started;
        fails only if the tick count stops moving for `STALL_S`."""
        last, since = -1, time.monotonic()
        while (n := self.ticks()) < target:
            if n != last:
                last, since = n, time.monotonic()
            elif time.monotonic() - since > STALL_S:
                raise VirtualStudyError(f"the worker stopped at {n} of {target} ticks "
                                        f"(no progress for {STALL_S:.0f} s)")
            time.sleep(self._sleep_s(target - n))

    def wait_run_over(self, run_id: int, seconds: float) -> None:
        """Until the worker has ended the timed run `run_id` (after `seconds` of device
        time): the trial then holds exactly that, however late this side looks. Fails
        only if the worker's ticks stop moving for `STALL_S`."""
        last, since = -1, time.monotonic()
        first: int | None = None  # the tick count at the first look, early in the run
        while True:
            h = ok(self.c.get("/api/health"))
            if h["database"]["current_run_id"] != run_id:
                return
            n = int(h["worker"]["ticks"])
            if first is None:
                first = n
            if n != last:
                last, since = n, time.monotonic()
            elif time.monotonic() - since > STALL_S:
                raise VirtualStudyError(f"run {run_id} did not end: no ticks for "
                                        f"{STALL_S:.0f} s ({seconds:.0f} s of device time "
                                        "were asked for)")
            # At most this many of the run's ticks are still to come.
            time.sleep(self._sleep_s(seconds / SAMPLE_PERIOD_S - (n - first)))

    def simulate(self, seed: int, script: str, speed: float) -> None:
        """Another virtual participant or script: the worker swaps its simulator."""
        self.speed = speed
        # Returns once the new wearer's ticks arrive.
        ok(self.c.post("/api/worker/simulation",
                       json={"seed": seed, "script": script, "speed": speed}))

    def job(self, job_id: int) -> None:
        """Until the job is done; fails if it fails, or makes no progress (status or
        fraction) for `STALL_S`."""
        last: tuple[str, float] | None = None
        since = time.monotonic()
        while True:
            job = ok(self.c.get(f"/api/jobs/{job_id}"))
            if job["status"] == "done":
                return
            if job["status"] in ("failed", "cancelled"):
                raise VirtualStudyError(f"job {job_id} {job['status']}: {job['message']}")
            state = (str(job["status"]), float(job.get("progress") or 0.0))
            if state != last:
                last, since = state, time.monotonic()
            elif time.monotonic() - since > STALL_S:
                raise VirtualStudyError(f"job {job_id} made no progress for {STALL_S:.0f} s")
            time.sleep(0.1)

    def calibrate(self, tries: int = 60) -> int:
        """Calibrate the E-UMC; the wearer has to stand still for 1 s, so retry while
        they move. Returns the number of attempts."""
        for attempt in range(1, tries + 1):
            r = self.c.post("/api/worker/calibrate", json={"seconds": 1.0})
            if r.status_code == 200:
                return attempt
            if r.status_code != 422:
                ok(r)
        raise VirtualStudyError(f"calibration failed {tries} times: the wearer never stood "
                                "still for a second")


def participant_body(seed: int, code: str) -> dict[str, Any]:
    """The participant record of the virtual participant `seed`, as an experimenter
    would enter it."""
    vp = VirtualParticipant.from_seed(seed)
    return {"code": code, "age": 20 + seed % 30, "sex": vp.sex,
            "height_m": round(vp.height_m, 3), "mass_kg": round(vp.mass_kg, 1),
            "consent_date": "2026-11-22",
            "notes": f"virtual participant, simulator seed {seed}"}


@functools.lru_cache(maxsize=256)
def script_duration_s(seed: int, script: str) -> float:
    """Device seconds of one repetition of `script` for the virtual participant `seed`
    (asked again for every trial: kept). The repetition's draws without its hip moments
    give the same durations at under half the cost."""
    return float(realise(get_script(script), VirtualParticipant.from_seed(seed), seed,
                         moments=False).duration)
