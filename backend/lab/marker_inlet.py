"""Marker streams of other software, read over LSL and stored with the running trial.

One thread per subscribed stream pulls its samples. A sample's time is the sender's LSL
clock; adding the inlet's `time_correction()` (which liblsl estimates continuously from
round trips) puts it on this machine's LSL clock, where the tick map of
`backend.lab.lsl_outlets` finds the tick, hence the run and the trial, it belongs to.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

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


class MarkerInlet:
    """Reads one marker stream until stopped; reconnects if the sender restarts."""

    def __init__(self, subscription_id: int, name: str, source_id: str,
                 on_marker: OnMarker) -> None:
        self.subscription_id = subscription_id
        self.name = name
        self.source_id = source_id
        self.on_marker = on_marker
        self.connected = False
        self.received = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"lsl-inlet-{subscription_id}")

    def start(self) -> None:
        """Begin resolving and reading."""
        self._thread.start()

    def stop(self, wait: bool = True) -> None:
        """Stop reading (within a second); without `wait`, only ask."""
        self._stop.set()
        if wait:
            self._thread.join(2.0)

    def _resolve(self) -> Any:
        import pylsl

        prop, value = ("source_id", self.source_id) if self.source_id else ("name", self.name)
        while not self._stop.is_set():
            found = pylsl.resolve_byprop(prop, value, minimum=1, timeout=1.0)
            if found:
                return found[0]
        return None

    def _run(self) -> None:
        import pylsl

        while not self._stop.is_set():
            info = self._resolve()
            if info is None:
                return
            inlet = pylsl.StreamInlet(info, max_buflen=60, recover=True)
            try:
                inlet.open_stream(timeout=5.0)
                self.connected = True
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
            except pylsl.LostError:
                log.warning("marker stream %s was lost; resolving it again", self.name)
            except TimeoutError:
                log.warning("marker stream %s did not answer; resolving it again", self.name)
            finally:
                self.connected = False
                inlet.close_stream()
