"""ExoStudy on the Lab Streaming Layer: a 100 Hz tick outlet and an irregular marker outlet.

LabRecorder records them beside the lab's other devices. Every sample is stamped with
the instant the worker read it from the device (`TickRecord.t_host`, Unix time) mapped
onto the LSL clock (`pylsl.local_clock()`, a monotonic clock), not with the time it is
sent: the worker hands ticks over in batches about every 20 ms, so a send-time stamp
would be late by up to a batch. The mapping is the difference between the two clocks,
read again at every batch (a wall-clock step, e.g. NTP, is followed within one batch).

The same map, kept for the last ticks, lets a marker arriving on the LSL clock (from the
console or another program) be placed on the tick time axis of a run.

pylsl is imported only when the outlets are switched on, so a server with
`EXOSTUDY_LSL_ENABLED=false` never loads liblsl.
"""

from __future__ import annotations

import bisect
import collections
import json
import logging
import math
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from backend.worker.messages import TickBatch
from controller.device.base import SAMPLE_RATE_HZ
from controller.tick_record import TICK_FIELD_DOCS

log = logging.getLogger(__name__)

#: (field, LSL channel type, unit) of each tick-stream channel, in order. Units follow the
#: tick record's own (radians, rad/s); the type names are those of the XDF meta-data
#: conventions for motion-capture-like channels, "Misc" where none fits.
TICK_CHANNELS: tuple[tuple[str, str, str], ...] = (
    ("seq", "Misc", "count"),
    ("q_raw_left", "JointAngle", "rad"),
    ("q_raw_right", "JointAngle", "rad"),
    ("q_left", "JointAngle", "rad"),
    ("q_right", "JointAngle", "rad"),
    ("omega_left", "JointAngularVelocity", "rad/s"),
    ("omega_right", "JointAngularVelocity", "rad/s"),
    ("post_squat", "Probability", "probability"),
    ("post_stoop_left", "Probability", "probability"),
    ("post_stoop_right", "Probability", "probability"),
    ("post_other", "Probability", "probability"),
    ("lock_left", "Command", "bool"),
    ("lock_right", "Command", "bool"),
    ("locked_left", "State", "bool"),
    ("locked_right", "State", "bool"),
)
TICK_CHANNEL_NAMES: tuple[str, ...] = tuple(c[0] for c in TICK_CHANNELS)

#: Ticks whose (LSL time, tick time, run) the map keeps: 30 s at 100 Hz, so a marker from
#: a program whose clock offset LSL is still estimating still finds its tick.
_MAP_LENGTH = 3000


@dataclass(frozen=True, slots=True)
class TickTime:
    """Where an LSL instant falls among the ticks: the run and its tick's device time."""

    run_id: int | None
    t: float
    lsl_time: float


def lsl_clock_offset(tries: int = 5) -> float:
    """LSL clock minus Unix time, now (seconds): the LSL reading bracketed by two Unix
    readings, the tightest bracket of a few (a pre-emption between the readings would
    otherwise shift the estimate by half its length)."""
    import pylsl

    best_width, best = math.inf, 0.0
    for _ in range(tries):
        before = time.time()
        lsl = pylsl.local_clock()
        after = time.time()
        if after - before < best_width:
            best_width, best = after - before, lsl - (before + after) / 2.0
        if best_width < 20e-6:
            break
    return float(best)


def marker_text(event: str, **fields: Any) -> str:
    """A marker sample: one JSON object with the event name first (LSL markers are
    strings; JSON keeps trial ids, sides and labels machine-readable in XDF files)."""
    return json.dumps({"event": event, **fields}, separators=(",", ":"), sort_keys=False)


class LabOutlets:
    """Both outlets, the tick-time map and the lock edges; fed on the supervisor's reader
    thread, used by request handlers (markers) and the marker inlets."""

    def __init__(self, enabled: bool, name: str = "ExoStudy") -> None:
        self.enabled = enabled
        self.name = name
        self._tick_outlet: Any = None
        self._marker_outlet: Any = None
        self._lock = threading.Lock()
        self._map_lsl: collections.deque[float] = collections.deque(maxlen=_MAP_LENGTH)
        self._map_t: collections.deque[float] = collections.deque(maxlen=_MAP_LENGTH)
        self._map_run: collections.deque[int | None] = collections.deque(maxlen=_MAP_LENGTH)
        self._runs: dict[int, int] = {}
        self._held: tuple[bool, bool] | None = None
        self.pushed_ticks = 0
        self.pushed_markers = 0

    # Life cycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Open the outlets (nothing when switched off)."""
        if not self.enabled:
            return
        import pylsl

        host = socket.gethostname()
        info = pylsl.StreamInfo(self.name, "ExoskeletonTicks", len(TICK_CHANNELS),
                                SAMPLE_RATE_HZ, pylsl.cf_double64,
                                f"exostudy-{self.name}-{host}-ticks")
        desc = info.desc()
        acq = desc.append_child("acquisition")
        acq.append_child_value("manufacturer", "ExoStudy")
        acq.append_child_value("model", "quasi-passive hip exoskeleton")
        acq.append_child_value("clock", "sample read time on the worker, mapped to LSL")
        chans = desc.append_child("channels")
        for field, kind, unit in TICK_CHANNELS:
            ch = chans.append_child("channel")
            ch.append_child_value("label", field)
            ch.append_child_value("unit", unit)
            ch.append_child_value("type", kind)
            ch.append_child_value("description", TICK_FIELD_DOCS[field][1])
        self._tick_outlet = pylsl.StreamOutlet(info, chunk_size=0, max_buffered=60)
        minfo = pylsl.StreamInfo(f"{self.name}-Markers", "Markers", 1, pylsl.IRREGULAR_RATE,
                                 pylsl.cf_string, f"exostudy-{self.name}-{host}-markers")
        mchans = minfo.desc().append_child("channels")
        mch = mchans.append_child("channel")
        mch.append_child_value("label", "event")
        mch.append_child_value("type", "Marker")
        mch.append_child_value("format", "JSON object with an 'event' key")
        self._marker_outlet = pylsl.StreamOutlet(minfo)

    def stop(self) -> None:
        """Close the outlets (consumers see the streams end)."""
        self._tick_outlet = None
        self._marker_outlet = None

    # Feeding (supervisor reader thread) --------------------------------------------
    def run_started(self, run_token: int, run_id: int) -> None:
        """A worker run token now means this `runs` row."""
        with self._lock:
            self._runs[run_token] = run_id

    def on_ticks(self, batch: TickBatch) -> tuple[TickTime, TickTime] | None:
        """Push a batch to the tick outlet, remember its times, mark lock edges; returns
        the batch's first and last tick (a batch holds ticks of one run). Works on the
        batch's columns: no per-tick Python beyond the lock edges."""
        ticks = batch.ticks
        if not len(ticks):
            return None
        offset = lsl_clock_offset() if self.enabled else time.monotonic() - time.time()
        with self._lock:
            run_id = self._runs.get(batch.run_token)
        t_host = ticks["t_host"]
        # A record without a read time (never from the live worker) is stamped now.
        stamps_a = np.where(np.isfinite(t_host), t_host, time.time()) + offset
        t_dev = ticks["t"].tolist()
        held = np.stack([ticks["lock_left"], ticks["lock_right"]], axis=1)
        # Each tick's command against the one before (the first tick ever has no edge).
        first = np.asarray(self._held if self._held is not None else held[0], dtype=bool)
        before = np.vstack([first[None, :], held[:-1]])
        edges: list[tuple[float, str, str, float]] = []
        for k, side_no in zip(*np.nonzero(held != before), strict=True):
            edges.append((float(stamps_a[k]), "lock" if held[k, side_no] else "release",
                          ("left", "right")[side_no], t_dev[k]))
        self._held = (bool(held[-1, 0]), bool(held[-1, 1]))
        stamps: list[float] = stamps_a.tolist()
        with self._lock:
            self._map_lsl.extend(stamps)
            self._map_t.extend(t_dev)
            self._map_run.extend([run_id] * len(stamps))
        outlet = self._tick_outlet
        if outlet is not None:
            chunk = np.stack([ticks[c].astype(np.float64) for c in TICK_CHANNEL_NAMES], axis=1)
            outlet.push_chunk(chunk, stamps)
            self.pushed_ticks += len(stamps)
        for ts, kind, side, t in edges:
            self.push_marker(marker_text(kind, side=side, run_id=run_id, t=t), ts)
        return (TickTime(run_id, t_dev[0], stamps[0]), TickTime(run_id, t_dev[-1], stamps[-1]))

    # Markers and the time map --------------------------------------------------------
    def push_marker(self, text: str, lsl_time: float) -> None:
        """Send one marker sample stamped `lsl_time` (nothing when switched off)."""
        outlet = self._marker_outlet
        if outlet is not None:
            outlet.push_sample([text], lsl_time)
            self.pushed_markers += 1

    def now(self) -> float:
        """The LSL clock now (Unix-time based when LSL is off, for the same arithmetic)."""
        if self.enabled:
            import pylsl

            return float(pylsl.local_clock())
        return time.monotonic()

    def latest(self) -> TickTime | None:
        """The newest tick seen, on both clocks."""
        with self._lock:
            if not self._map_lsl:
                return None
            return TickTime(self._map_run[-1], self._map_t[-1], self._map_lsl[-1])

    def tick_at(self, lsl_time: float) -> TickTime | None:
        """The tick nearest to an LSL instant among the last ticks (None before the first
        tick or more than one second outside the kept ones)."""
        with self._lock:
            stamps = list(self._map_lsl)
            if not stamps:
                return None
            i = bisect.bisect_left(stamps, lsl_time)
            cands = [j for j in (i - 1, i) if 0 <= j < len(stamps)]
            j = min(cands, key=lambda k: abs(stamps[k] - lsl_time))
            if abs(stamps[j] - lsl_time) > 1.0:
                return None
            return TickTime(self._map_run[j], self._map_t[j], stamps[j])
