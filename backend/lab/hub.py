"""The lab integration of one server process: LSL outlets, marker inlets, and markers
stored, streamed to consoles and sent on LSL at once.

The runtime feeds it the worker's tick batches and run starts (one more consumer beside
the recorder and the live stream, attached by the app factory: `backend.live.parts`);
routes call it for console markers and trial events. Markers reach the consoles through
the `broadcast` it is given (the live stream's), so the lab imports nothing of the live
path.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Callable
from typing import Any

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.db.evidence_tables import Trial
from backend.db.lab import Marker, MarkerStream
from backend.lab import markers
from backend.lab.lsl_outlets import LabOutlets, TickTime, marker_text
from backend.lab.marker_inlet import MarkerInlet
from backend.lsl import names as lsl_names
from backend.schemas.lab import LiveMarker, MarkerOut
from backend.worker.messages import TickBatch

log = logging.getLogger(__name__)


class Lab:
    """Outlets, inlets and markers for one server."""

    def __init__(self, enabled: bool, name: str, engine: Engine,
                 broadcast: Callable[[dict[str, Any]], None]) -> None:
        self.outlets = LabOutlets(enabled, name)
        self.engine = engine
        #: Sends a JSON message to every console (`LiveStream.broadcast_json`).
        self.broadcast = broadcast
        self.inlets: dict[int, MarkerInlet] = {}
        self._first: dict[int, TickTime] = {}
        self._last: dict[int, TickTime] = {}
        self._lock = threading.Lock()

    @property
    def enabled(self) -> bool:
        """Whether LSL is on (setting `lsl_enabled`)."""
        return self.outlets.enabled

    def start(self) -> None:
        """Open the outlets and resume the active subscriptions. A stored subscription
        whose name the resolver cannot search for (stored before names were checked)
        is closed as failed instead of resumed."""
        self.outlets.start()
        with Session(self.engine) as db:
            resume = []
            for sub in db.scalars(select(MarkerStream).where(MarkerStream.active)):
                why = lsl_names.problem(sub.source_id or sub.name)
                if why is None and sub.source_id:
                    why = lsl_names.problem(sub.name)
                if why is not None:
                    sub.active = False
                    sub.error = why
                    log.warning("marker stream subscription %d closed at start: %s",
                                sub.id, why)
                else:
                    resume.append((sub.id, sub.name, sub.source_id))
            db.commit()
        if not self.enabled:
            return
        for sub_id, name, source_id in resume:
            self.subscribe(sub_id, name, source_id)

    def stop(self) -> None:
        """Stop every inlet, then close the outlets."""
        inlets = list(self.inlets.values())
        for inlet in inlets:  # all asked first, so they stop together
            inlet.stop(wait=False)
        for inlet in inlets:
            inlet.stop()
        self.inlets.clear()
        self.outlets.stop()

    # The runtime's hooks (supervisor reader thread) ----------------------------------
    def on_run_started(self, run_token: int, run_id: int) -> None:
        """A run began: its ticks are stamped with its id."""
        self.outlets.run_started(run_token, run_id)

    def on_ticks(self, batch: TickBatch) -> None:
        """Tick outlet, lock edges, and each run's first and last tick."""
        edges = self.outlets.on_ticks(batch)
        run_id = edges[0].run_id if edges is not None else None
        if edges is not None and run_id is not None:
            with self._lock:
                self._first.setdefault(run_id, edges[0])
                self._last[run_id] = edges[1]

    def on_calibration(self, ok: bool, message: str) -> None:
        """Calibrations go on the LSL marker stream (they concern no one trial)."""
        tick = self.outlets.latest()
        self.outlets.push_marker(marker_text("calibration", ok=ok, message=message),
                                 tick.lsl_time if tick else self.outlets.now())

    # Markers ------------------------------------------------------------------------------
    def _send(self, marker: Marker, extra: dict[str, Any] | None = None) -> None:
        """Send a marker on LSL, stamped with its tick's LSL time."""
        fields: dict[str, Any] = {"label": marker.label, "note": marker.note,
                                  "source": marker.source, "session_id": marker.session_id,
                                  "trial_id": marker.trial_id, "t": marker.t}
        fields.update(extra or {})
        text = marker_text("marker" if marker.source != "system" else marker.label, **fields)
        self.outlets.push_marker(text, marker.lsl_time if marker.lsl_time is not None
                                 else self.outlets.now())

    def publish(self, marker: Marker, extra: dict[str, Any] | None = None,
                send: bool = True) -> None:
        """Send a stored marker on LSL (unless `send` is off) and to the consoles."""
        if send:
            self._send(marker, extra)
        self.broadcast(
            LiveMarker(marker=MarkerOut.model_validate(marker)).model_dump(mode="json"))

    def console_marker(self, db: Session, session_id: int, label: str, note: str,
                       user_id: int | None) -> Marker:
        """A marker from the console at the newest tick. It goes on LSL first (the
        insert may wait for the tick recorder's write lock; LabRecorder should not),
        then it is stored (committed) and shown on the consoles."""
        tick = self.outlets.latest()
        markers.check_console_tick(db, session_id, tick)
        marker = markers.store(db, session_id, label, note, "console", tick,
                               lsl_time=None if tick else self.outlets.now(), user_id=user_id,
                               flush=False)
        self._send(marker)
        db.commit()
        db.refresh(marker)
        self.publish(marker, send=False)
        return marker

    async def trial_event(self, db: Session, session_id: int, trial_id: int, run_id: int,
                          event: str, fields: dict[str, Any], timeout: float = 2.0) -> None:
        """Mark a trial's start (at its run's first tick) or stop (at its last tick):
        stored with the trial and sent on LSL. Waits up to `timeout` for the first tick."""
        edge = self._first if event == "trial_start" else self._last
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while loop.time() < deadline:
            with self._lock:
                tick = edge.get(run_id)
            if tick is not None:
                break
            await asyncio.sleep(0.01)
        if tick is None:
            tick = TickTime(run_id, float("nan"), self.outlets.now())
        marker = Marker(session_id=session_id, trial_id=trial_id, run_id=run_id,
                        t=tick.t if tick.t == tick.t else None, lsl_time=tick.lsl_time,
                        label=event, note="", source="system")
        db.add(marker)
        db.commit()
        db.refresh(marker)
        self.publish(marker, fields)

    async def trial_marker(self, db: Session, trial: Trial, event: str) -> None:
        """`trial_start` or `trial_stop` of a trial that ran, with its blinded label and
        controller."""
        if trial.run_id is None:
            return
        await self.trial_event(db, trial.session_id, trial.id, trial.run_id, event,
                               markers.trial_fields(db, trial))

    # Inlets -------------------------------------------------------------------------------
    def subscribe(self, sub_id: int, name: str, source_id: str) -> None:
        """Start reading a marker stream for subscription `sub_id`."""
        if not self.enabled or sub_id in self.inlets:
            return
        inlet = MarkerInlet(sub_id, name, source_id, self._store_inlet_marker,
                            self._inlet_failed)
        self.inlets[sub_id] = inlet
        inlet.start()

    def _inlet_failed(self, sub_id: int, why: str) -> None:
        """An inlet gave up (its thread ends): the subscription is closed and says why,
        so it is neither shown as listening nor resumed at the next start."""
        self.inlets.pop(sub_id, None)
        with Session(self.engine) as db:
            sub = db.get(MarkerStream, sub_id)
            if sub is not None:
                sub.active = False
                sub.error = why[:1000]
                db.commit()

    def unsubscribe(self, sub_id: int) -> None:
        """Stop reading a marker stream."""
        inlet = self.inlets.pop(sub_id, None)
        if inlet is not None:
            inlet.stop()

    def _store_inlet_marker(self, sub_id: int, text: str, lsl_time: float) -> None:
        tick = self.outlets.tick_at(lsl_time)
        with Session(self.engine) as db:
            sub = db.get(MarkerStream, sub_id)
            if sub is None or not sub.active:
                return
            marker = markers.store(db, sub.session_id, text, "", "lsl", tick,
                                   lsl_time=lsl_time, stream_id=sub_id)
            db.commit()
            db.refresh(marker)
            self.publish(marker, send=False)  # already on the network
