"""The soft real-time control loop: read a sample, run the controller, send the command.

The same loop runs live (in the backend's worker process, paced by the device) and
offline (replay, virtual studies: a device that never waits). It measures its own
timing so that a study can show it held 100 Hz.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from controller.device.base import SAMPLE_PERIOD_S, Device, LockCommand
from controller.interface import Controller
from controller.tick_record import TickFlag, TickRecord


@dataclass(frozen=True, slots=True)
class TimingSummary:
    """Loop timing over the recent window (milliseconds unless stated)."""

    ticks: int
    period_mean_ms: float
    jitter_p50_ms: float
    jitter_p99_ms: float
    jitter_max_ms: float
    compute_p50_us: float
    compute_p99_us: float
    compute_max_us: float
    overruns: int
    gaps: int
    timeouts: int


class LoopTiming:
    """Ring buffers of tick periods and compute times.

    Jitter is the absolute deviation of the period between consecutive samples from the
    nominal period. An overrun is a tick whose processing (controller and send) took
    longer than the nominal period, so the next sample was already waiting.
    """

    def __init__(self, period_s: float = SAMPLE_PERIOD_S, window: int = 2000) -> None:
        self.period_s = period_s
        self._periods = np.full(window, np.nan)
        self._compute = np.full(window, np.nan)
        self._i = 0
        self.ticks = 0
        self.overruns = 0
        self.gaps = 0
        self.timeouts = 0
        self._last_start: float | None = None

    def record(self, start: float, end: float) -> bool:
        """Register a tick that began at `start` and finished at `end` (monotonic s).
        Returns True if it overran."""
        j = self._i % self._periods.size
        self._periods[j] = np.nan if self._last_start is None else start - self._last_start
        self._compute[j] = end - start
        self._last_start = start
        self._i += 1
        self.ticks += 1
        overrun = end - start > self.period_s
        if overrun:
            self.overruns += 1
        return overrun

    def summary(self) -> TimingSummary:
        """Statistics over the window."""
        p = self._periods[~np.isnan(self._periods)]
        c = self._compute[~np.isnan(self._compute)]
        jit = np.abs(p - self.period_s) * 1e3 if p.size else np.array([math.nan])
        c_us = c * 1e6 if c.size else np.array([math.nan])
        return TimingSummary(
            ticks=self.ticks,
            period_mean_ms=float(p.mean() * 1e3) if p.size else math.nan,
            jitter_p50_ms=float(np.percentile(jit, 50)),
            jitter_p99_ms=float(np.percentile(jit, 99)),
            jitter_max_ms=float(jit.max()),
            compute_p50_us=float(np.percentile(c_us, 50)),
            compute_p99_us=float(np.percentile(c_us, 99)),
            compute_max_us=float(c_us.max()),
            overruns=self.overruns,
            gaps=self.gaps,
            timeouts=self.timeouts,
        )


class ControlLoop:
    """Drives one controller on one device.

    `tick()` blocks until the device delivers a sample (the device sets the pace), so the
    loop has no sleep of its own and cannot drift from the device clock. A controller
    that raises, which it must not, still yields a flagged tick and a no-lock command.
    """

    def __init__(
        self,
        device: Device,
        controller: Controller,
        period_s: float = SAMPLE_PERIOD_S,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        self.device = device
        self.controller = controller
        self.timing = LoopTiming(period_s)
        self._clock = clock
        self._last_seq: int | None = None
        self._cmd_seq = 0
        self.last_sample_at: float | None = None
        #: Ticks whose sample failed a plausibility check (for health).
        self.implausible = 0
        #: Asked before any lock is sent: "" if the device on the link may be locked
        #: now, else why not (the worker's check that the controller's encoder layout
        #: belongs to this device). A refused tick's lock is not sent, nor recorded.
        self.lock_gate: Callable[[], str] | None = None
        #: Ticks whose lock `lock_gate` withheld.
        self.withheld = 0

    def tick(self, timeout: float = 0.05) -> TickRecord | None:
        """One iteration; None when no sample arrived within `timeout` seconds."""
        sample = self.device.read(timeout)
        if sample is None:
            self.timing.timeouts += 1
            return None
        start = self._clock()
        self.last_sample_at = time.monotonic()
        gap = self._last_seq is not None and sample.seq != self._last_seq + 1
        self._last_seq = sample.seq
        try:
            record = self.controller.step(sample)
        except Exception:
            record = TickRecord(
                seq=sample.seq, t=sample.t, t_host=time.time(), flags=int(TickFlag.CONTROLLER_ERROR)
            )
        if record.plausibility:
            self.implausible += 1
        if gap:
            self.timing.gaps += 1
            record = record.with_(flags=record.flags | int(TickFlag.GAP))
        if (record.lock_left or record.lock_right) and self.lock_gate is not None \
                and self.lock_gate():
            self.withheld += 1
            record = record.with_(lock_left=False, lock_right=False)
        self._cmd_seq += 1
        self.device.send(LockCommand(self._cmd_seq, record.lock_left, record.lock_right))
        overrun = self.timing.record(start, self._clock())
        if overrun:
            record = record.with_(flags=record.flags | int(TickFlag.OVERRUN))
        return record
