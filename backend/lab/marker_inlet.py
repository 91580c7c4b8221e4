"""Marker streams of other software, read over LSL and stored with the running trial.

One thread per subscribed stream pulls its samples. A sample's time is the sender's LSL
clock; adding the inlet's `time_correction()` (which liblsl estimates continuously from
round trips) puts it on this machine's LSL clock, where the tick map of
`backend.lab.lsl_outlets` finds the tick, hence the run and the trial, it belongs to.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from backend.lsl.backoff import backoff_delays
from backend.lsl.names import Property, lsl_errors, predicate

log = logging.getLogger(__name__)

#: Seconds a pull waits for a sample before looking at the stop flag again.
_PULL_TIMEOUT_S = 0.2


@dataclass(frozen=True, slots=True)
class VisibleStream:
    """An LSL stream found on the network."""

    name: str
    type: str
    source_id: str
    hostname: str
    channel_count: int
    nominal_srate: float


def visible_streams(wait_s: float = 1.0) -> list[VisibleStream]:
    """Every LSL stream that answers within `wait_s` seconds."""
    import pylsl

    out = []
    for info in pylsl.resolve_streams(wait_time=wait_s):
        out.append(VisibleStream(info.name(), info.type(), info.source_id(), info.hostname(),
                                 info.channel_count(), info.nominal_srate()))
    out.sort(key=lambda s: (s.type != "Markers", s.name, s.source_id))
    return out


#: Called on the inlet's thread for each marker: (subscription id, text, local LSL time).
OnMarker = Callable[[int, str, float], None]
#: Called once, on the inlet's thread, when the inlet gives up: (subscription id, why).
OnFailed = Callable[[int, str], None]

#: Seconds one resolve round waits for the stream to appear.
_RESOLVE_TIMEOUT_S = 1.0
#: Consecutive failed connection attempts (the stream was found but could not be
#: opened, or the reader failed) after which the subscription is closed as failed.
MAX_FAILURES = 8


class MarkerInlet:
    """Reads one marker stream until stopped; reconnects if the sender restarts, with
    a bounded backoff, and gives up (`on_failed`) on a query liblsl refuses or on
    repeated failures, never retrying in a tight loop."""

    def __init__(self, subscription_id: int, name: str, source_id: str,
                 on_marker: OnMarker, on_failed: OnFailed | None = None) -> None:
        self.subscription_id = subscription_id
        self.name = name
        self.source_id = source_id
        self.on_marker = on_marker
        self.on_failed = on_failed
        self.connected = False
        self.received = 0
        #: Why the inlet gave up ("" while it runs).
        self.failure = ""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"lsl-inlet-{subscription_id}")

    def start(self) -> None:
        """Begin resolving and reading."""
        self._thread.start()

    def stop(self, wait: bool = True) -> None:
        """Stop reading (within a second); without `wait`, only ask."""
        self._stop.set()
        if wait and self._thread is not threading.current_thread():
            self._thread.join(2.0)

    @property
    def alive(self) -> bool:
        """Whether the reading thread still runs."""
        return self._thread.is_alive()

    def _sleep(self, seconds: float) -> bool:
        """Wait, or less if stopped; True if stopped (tests replace it)."""
        return self._stop.wait(seconds)

    def _query(self) -> str:
        prop: Property = "source_id" if self.source_id else "name"
        return predicate(prop, self.source_id or self.name)

    def _resolve(self, query: str) -> Any:
        import pylsl

        delays = backoff_delays()
        while not self._stop.is_set():
            began = time.monotonic()
            found = pylsl.resolve_bypred(query, minimum=1, timeout=_RESOLVE_TIMEOUT_S)
            if found:
                return found[0]
            # A round that returns early did not wait for the stream: back off instead
            # of asking again at once.
            if time.monotonic() - began < _RESOLVE_TIMEOUT_S / 2 and self._sleep(next(delays)):
                return None
        return None

    def _fail(self, why: str) -> None:
        self.failure = why
        log.warning("marker stream subscription %d (%s) closed: %s", self.subscription_id,
                    self.name, why)
        if self.on_failed is not None:
            try:
                self.on_failed(self.subscription_id, why)
            except Exception:
                log.exception("recording the failure of subscription %d failed",
                              self.subscription_id)

    def _run(self) -> None:
        try:
            query = self._query()
        except ValueError as exc:
            self._fail(str(exc))
            return
        delays = backoff_delays()
        failures = 0
        while not self._stop.is_set():
            try:
                info = self._resolve(query)
                if info is None:
                    return
                if self._read(info):
                    failures = 0
                    delays = backoff_delays()
                    continue
            except Exception as exc:  # liblsl raises plain RuntimeError and others
                log.warning("marker stream %s: %s", self.name, exc)
            failures += 1
            if failures >= MAX_FAILURES:
                self._fail(f"{failures} failed attempts to read the stream")
                return
            if self._sleep(next(delays)):
                return

    def _read(self, info: Any) -> bool:
        """Read samples until stopped or the stream is lost; True if it was read at all
        (a later loss is a reconnection, not a failure)."""
        import pylsl

        inlet = pylsl.StreamInlet(info, max_buflen=60, recover=True)
        # pylsl 1.17 moved its exceptions (and its TimeoutError is not the built-in
        # one): naming `pylsl.LostError` in an except clause raised AttributeError there.
        lost_error, timeout_error = lsl_errors(pylsl)
        got_any = False
        try:
            inlet.open_stream(timeout=5.0)
            self.connected = True
            got_any = True
            correction = inlet.time_correction(timeout=5.0)
            while not self._stop.is_set():
                sample, ts = inlet.pull_sample(timeout=_PULL_TIMEOUT_S)
                if sample is None or ts is None:
                    continue
                # A cheap call after the first: liblsl updates the estimate itself.
                correction = inlet.time_correction(timeout=1.0)
                text = str(sample[0]) if sample else ""
                self.received += 1
                try:
                    self.on_marker(self.subscription_id, text, float(ts + correction))
                except Exception:
                    log.exception("storing a marker of %s failed", self.name)
        except lost_error:
            log.warning("marker stream %s was lost; resolving it again", self.name)
        except timeout_error:
            log.warning("marker stream %s did not answer; resolving it again", self.name)
        finally:
            self.connected = False
            inlet.close_stream()
        return got_any
