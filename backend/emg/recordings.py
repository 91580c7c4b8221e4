"""Storing an EMG recording: montage mapping, the file, its row, its trials and flags.

Every source (a live LSL stream, an EDF/BDF or XDF import) ends here: channels are
mapped to the study's montage by label (a label that matches no montage entry refuses
the whole recording: `ChannelMismatchError`, nothing stored), the rows go to a file in
blocks (`backend.emg.store`), quality is assessed on the way, and the row says which of
the session's trials the recording covers. A failure on the way removes the file and
the row, so a half-written recording never looks like a recording.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db import audit
from backend.db.emg import EmgMontage, EmgRecording
from backend.db.lab import Marker
from backend.db.models import Participant, StudySession, User
from backend.db.sessions import session_row
from backend.emg import bids, recovery, store
from backend.emg.quality_summary import STOPPED_MID_TRIAL, QualitySummary
from controller.emg.montage import Montage, MontageError, normalise_label
from controller.emg.processing import MIN_UPPER_EDGE_HZ, NYQUIST_MARGIN

#: Sources a recording may come from.
SOURCES = ("lsl", "xdf", "edf", "bdf", "simulated")
#: Units a stream or file may state for its EMG channels, with the factor to volts.
UNITS_TO_VOLTS = {"v": 1.0, "volt": 1.0, "volts": 1.0, "mv": 1e-3, "millivolt": 1e-3,
                  "millivolts": 1e-3, "uv": 1e-6, "µv": 1e-6, "μv": 1e-6,
                  "microvolt": 1e-6, "microvolts": 1e-6}


class ChannelMismatchError(ValueError):
    """Recording labels that no montage channel claims (or montage channels missing)."""

    def __init__(self, unmatched: list[str], missing: list[str], expected: list[str]) -> None:
        self.unmatched = unmatched
        self.missing = missing
        self.expected = expected
        parts = []
        if unmatched:
            parts.append(f"channel labels {unmatched} match no entry of the study's montage")
        if missing:
            parts.append(f"montage channels {missing} are not in the recording")
        super().__init__("; ".join(parts) + f"; the montage expects {expected} (list "
                         "spare inputs under ignore_labels to leave them out)")


#: Lowest rate an imported file may have: the processing chain's band-pass needs an
#: upper edge of `MIN_UPPER_EDGE_HZ` at `NYQUIST_MARGIN` of Nyquist (about 210.5 Hz).
MIN_IMPORT_RATE_HZ = 2.0 * MIN_UPPER_EDGE_HZ / NYQUIST_MARGIN
#: Highest: no surface EMG amplifier samples faster (high-density systems reach 10 kHz),
#: so a higher stated rate is a damaged header, not EMG.
MAX_IMPORT_RATE_HZ = 100_000.0


def check_import_rate(fs: float) -> None:
    """ValueError naming the rate when an imported file's rate is no EMG rate."""
    if not (math.isfinite(fs) and MIN_IMPORT_RATE_HZ <= fs <= MAX_IMPORT_RATE_HZ):
        raise ValueError(f"sampling rate {fs!r} Hz is not a surface EMG rate: it must be "
                         f"{MIN_IMPORT_RATE_HZ:.1f} Hz (twice the {MIN_UPPER_EDGE_HZ:g} Hz "
                         f"band-pass upper edge the processing needs, at "
                         f"{NYQUIST_MARGIN:.0%} of Nyquist) to {MAX_IMPORT_RATE_HZ:g} Hz")


class NoMontageError(ValueError):
    """The study has no montage yet: channels cannot be mapped to muscles."""


def volts_per_unit(unit: str) -> float:
    """Factor from a stated unit to volts; ValueError for a unit that is not a voltage."""
    factor = UNITS_TO_VOLTS.get(unit.strip().casefold())
    if factor is None:
        raise ValueError(f"unit {unit!r} is not a voltage (V, mV or uV)")
    return factor


def current_montage(db: Session, study_id: int) -> EmgMontage | None:
    """The study's newest montage version."""
    return db.scalars(select(EmgMontage).where(EmgMontage.study_id == study_id)
                      .order_by(EmgMontage.version.desc()).limit(1)).first()


def session_montage(db: Session, session_id: int) -> EmgMontage:
    """The current montage of the session's study, or `NoMontageError`."""
    study_id = db.scalar(select(Participant.study_id).join(
        StudySession, StudySession.participant_id == Participant.id)
        .where(StudySession.id == session_id))
    row = current_montage(db, study_id) if study_id is not None else None
    if row is None:
        raise NoMontageError(f"the study of session {session_id} has no EMG montage: "
                             f"PUT /api/studies/{study_id}/emg-montage first")
    return row


def montage_of(row: EmgMontage) -> Montage:
    """The stored version as the controller's record."""
    return Montage.from_dict({"channels": row.channels})


def map_channels(row: EmgMontage, labels: list[str], ignore: Iterable[str] = ()
                 ) -> list[int]:
    """The recording's column of each montage channel, in montage order. Every label
    must be a montage channel or listed in `ignore`, and every montage channel present;
    otherwise `ChannelMismatchError` listing both sides."""
    montage = montage_of(row)
    skip = {normalise_label(lb) for lb in ignore}
    try:
        match = montage.match(labels)
    except MontageError as exc:
        raise ValueError(str(exc)) from exc
    unmatched = [lb for lb in match.unmatched_labels if normalise_label(lb) not in skip]
    expected = [c.label for c in montage.channels]
    if unmatched or match.missing:
        raise ChannelMismatchError(unmatched, list(match.missing), expected)
    return [i for i in match.indices if i is not None]


def trial_spans(db: Session, session_id: int) -> list[dict[str, Any]]:
    """The session's trials on the session clock, from their start and stop markers
    (stop None: still running)."""
    spans: dict[int, dict[str, Any]] = {}
    for m in db.scalars(select(Marker).where(
            Marker.session_id == session_id, Marker.source == "system",
            Marker.label.in_(("trial_start", "trial_stop")), Marker.trial_id.is_not(None),
            Marker.lsl_time.is_not(None)).order_by(Marker.id)):
        assert m.trial_id is not None
        span = spans.setdefault(m.trial_id, {"trial_id": m.trial_id, "start": None,
                                             "stop": None})
        span["start" if m.label == "trial_start" else "stop"] = m.lsl_time
    return [s for s in spans.values() if s["start"] is not None]


def covered_trials(db: Session, session_id: int, t_start: float | None, t_end: float | None
                   ) -> list[dict[str, Any]]:
    """Trials overlapping [t_start, t_end] (session clock), each marked `complete` when
    the recording spans the whole trial."""
    if t_start is None or t_end is None:
        return []
    out = []
    for s in trial_spans(db, session_id):
        stop = s["stop"] if s["stop"] is not None else float("inf")
        if s["start"] <= t_end and stop >= t_start:
            out.append({**s, "complete": bool(t_start <= s["start"] and stop <= t_end)})
    return out


def stopped_inside(t_start: float | None, t_end: float | None, span: dict[str, Any]) -> bool:
    """Whether a recording [t_start, t_end] ended inside the trial `span` (session clock):
    it was recording when the trial started and stopped before the trial's stop (a file
    that only covers a stretch inside the trial is not a stream that stopped). A trial
    still running (stop None) is not decided yet: False, asked again once its stop is
    known."""
    stop = span.get("stop")
    if t_start is None or t_end is None or stop is None:
        return False
    return bool(t_start <= span["start"] <= t_end < stop)


Block = tuple[NDArray[Any] | None, NDArray[Any]]


class RecordingWriter:
    """A recording being written: the row exists (status "recording") from the start,
    so the live page lists it; `finish` fills in the file's hash, span, trials and flags.
    """

    def __init__(self, db: Session, settings: Settings, session_id: int, montage: EmgMontage,
                 source: str, fs: float, time_offset_s: float = 0.0, alignment: str = "",
                 filename: str = "", stream_id: int | None = None,
                 user_id: int | None = None, mains_hz: int | None = None) -> None:
        if source not in SOURCES:
            raise ValueError(f"source must be one of {SOURCES}, got {source!r}")
        if not np.isfinite(fs) or fs <= 0:
            raise ValueError(f"sampling rate must be positive, got {fs}")
        labels = [c["label"] for c in montage.channels]
        self.quality = QualitySummary(float(fs), labels, mains_hz)  # refuses before the row
        self.db = db
        self.row = EmgRecording(
            session_id=session_id, montage_id=montage.id, montage_version=montage.version,
            source=source, stream_id=stream_id, status="recording", filename=filename[:255],
            fs=float(fs), channel_count=len(labels), labels=labels, n_samples=0,
            time_offset_s=float(time_offset_s), alignment=alignment, trials=[],
            size_bytes=0, sha256="", quality={}, created_by=user_id)
        db.add(self.row)
        db.commit()
        self.path = store.recording_path(settings, self.row.id)
        # SQLite may give a deleted recording's id again: a file left under it (an
        # erasure whose deletion failed) is moved aside, never overwritten.
        for old in (self.path, self.path.with_name(self.path.name + ".part")):
            if old.exists():
                recovery.set_aside(old)
        try:
            self.writer = store.EmgWriter(self.path, labels, fs)
        except Exception:
            self._drop_row()
            raise

    def append(self, timestamps: NDArray[Any], samples: NDArray[Any]) -> None:
        """Rows in montage order, volts; timestamps on the file's own clock."""
        self.writer.append(timestamps, samples)
        self.quality.add(timestamps, samples)

    def finish(self) -> EmgRecording:
        """Close the file and complete the row (committed)."""
        sha, rows = self.writer.close()
        self.quality.finish()
        row = self.row
        off = row.time_offset_s
        row.n_samples = rows
        row.sha256 = sha
        row.size_bytes = self.path.stat().st_size
        w = self.writer
        row.t_start = None if w.first_t is None else w.first_t + off
        row.t_end = None if w.last_t is None else w.last_t + off
        row.trials = covered_trials(self.db, row.session_id, row.t_start, row.t_end)
        if any(stopped_inside(row.t_start, row.t_end, t) for t in row.trials):
            self.quality.flag(STOPPED_MID_TRIAL)
        row.quality = self.quality.to_dict()
        row.status = "complete"
        self.db.commit()
        return row

    def abort(self) -> None:
        """Remove the file and the row: nothing of a failed recording stays."""
        self.writer.abort()
        self._drop_row()

    def _drop_row(self) -> None:
        self.db.rollback()
        row = self.db.get(EmgRecording, self.row.id)
        if row is not None:
            self.db.delete(row)
            self.db.commit()


def store_blocks(db: Session, settings: Settings, session_id: int, montage: EmgMontage,
                 source: str, fs: float, blocks: Iterable[Block], time_offset_s: float,
                 alignment: str, filename: str = "", user_id: int | None = None,
                 mains_hz: int | None = None, flags: Iterable[str] = ()) -> EmgRecording:
    """Write a whole recording from blocks (timestamps None: at the nominal rate from 0)
    in montage order, with `flags` of the recording as a whole; on any error nothing is
    kept. A rate no BDF record length holds (see `bids.record_duration`) is refused
    before anything is stored, so every imported recording can be exported."""
    check_import_rate(fs)
    bids.record_duration(fs)
    rec = RecordingWriter(db, settings, session_id, montage, source, fs, time_offset_s,
                          alignment, filename, user_id=user_id, mains_hz=mains_hz)
    for name in flags:
        rec.quality.flag(name)
    n = 0
    try:
        for t, x in blocks:
            rows = np.asarray(x).shape[0]
            ts = np.arange(n, n + rows) / fs if t is None else t
            rec.append(ts, x)
            n += rows
        if n == 0:
            raise ValueError("the recording holds no samples")
        return rec.finish()
    except BaseException:
        rec.abort()
        raise


def delete_file(settings: Settings, recording_id: int) -> None:
    """Remove a recording's file (its row is deleted by the caller)."""
    Path(store.recording_path(settings, recording_id)).unlink(missing_ok=True)


def session_recordings(db: Session, session_id: int) -> list[EmgRecording]:
    """The session's recordings, oldest first."""
    return list(db.scalars(select(EmgRecording).where(EmgRecording.session_id == session_id)
                           .order_by(EmgRecording.id)))


def session_recording(db: Session, session_id: int, recording_id: int) -> EmgRecording:
    """One recording of the session; `NotFoundError` otherwise."""
    return session_row(db, EmgRecording, session_id, recording_id, "EMG recording")


def record_import(db: Session, user: User, row: EmgRecording) -> EmgRecording:
    """Write who imported a stored file into the audit trail; commits."""
    audit.record(db, user, "create", "emg_recording", row.id,
                 {"source": row.source, "sha256": row.sha256, "filename": row.filename})
    db.commit()
    return row
