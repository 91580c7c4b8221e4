"""EMG from an EDF or BDF file (read with `edfio`), aligned through the session's events.

An amplifier's own software writes EDF/BDF on its own clock, which the session does not
know. Two ways to place the file on the session clock, the request chooses:

- `marker`: the file holds an annotation (EDF+/BDF+) whose text equals the label of one
  of the session's markers, e.g. a `sync` pulse the experimenter marked in both; the
  first annotation and the first marker with that text are the same instant.
- `trial` and `offset_s`: the file's first sample is `offset_s` seconds after the start
  of the session's trial `trial` (its `trial_start` marker), as the lab noted it.

Channels are mapped to the study's montage by label; the unit (physical dimension)
must be a voltage and is converted to volts; every mapped channel must share one
sampling rate. The signals are read in blocks of `BLOCK_S` seconds.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.emg import EmgRecording
from backend.db.lab import Marker
from backend.emg import recordings
from backend.emg.recordings import Block

BLOCK_S = 5.0
#: BDF files begin with byte 255 and "BIOSEMI"; EDF with "0" and spaces.
BDF_MAGIC = b"\xffBIOSEMI"


@dataclass(frozen=True, slots=True)
class Alignment:
    """How the file's clock maps to the session's (exactly one way)."""

    marker: str | None = None
    trial: int | None = None
    offset_s: float = 0.0


def read(data: bytes) -> tuple[Any, str]:
    """The file as edfio's object and its kind ("edf" or "bdf"); ValueError with the
    reader's reason for a file that is neither."""
    import edfio

    kind = "bdf" if data.startswith(BDF_MAGIC) else "edf"
    try:
        edf = (edfio.read_bdf if kind == "bdf" else edfio.read_edf)(io.BytesIO(data))
    except Exception as exc:  # edfio raises ValueError, IndexError, UnicodeDecodeError ...
        raise ValueError(f"not a readable {kind.upper()} file: {exc}") from exc
    return edf, kind


def offset(db: Session, session_id: int, edf: Any, how: Alignment) -> tuple[float, str]:
    """Session clock minus file time, and the sentence saying how it was found."""
    if (how.marker is None) == (how.trial is None):
        raise ValueError("say how to align the file: either `marker` (an annotation text "
                         "that is also a session marker's label) or `trial` and `offset_s`")
    if how.marker is not None:
        onsets = [float(a.onset) for a in edf.annotations if a.text == how.marker]
        if not onsets:
            texts = sorted({a.text for a in edf.annotations})[:20]
            raise ValueError(f"the file has no annotation {how.marker!r} (its annotations: "
                             f"{texts})")
        m = db.scalars(select(Marker).where(Marker.session_id == session_id,
                                            Marker.label == how.marker,
                                            Marker.lsl_time.is_not(None))
                       .order_by(Marker.lsl_time)).first()
        if m is None or m.lsl_time is None:
            raise ValueError(f"session {session_id} has no marker {how.marker!r} to align "
                             "the file's annotation with")
        return m.lsl_time - onsets[0], (f"annotation {how.marker!r} at {onsets[0]:.6f} s of "
                                        f"the file = session marker {m.id}")
    start = db.scalars(select(Marker).where(Marker.session_id == session_id,
                                            Marker.trial_id == how.trial,
                                            Marker.label == "trial_start",
                                            Marker.lsl_time.is_not(None))).first()
    if start is None or start.lsl_time is None:
        raise ValueError(f"trial {how.trial} of session {session_id} has no start marker "
                         "(has it run?)")
    if not math.isfinite(how.offset_s):
        raise ValueError("offset_s must be finite")
    return start.lsl_time + how.offset_s, (f"file start {how.offset_s:g} s after the start "
                                           f"of trial {how.trial} (marker {start.id})")


def import_file(db: Session, settings: Settings, session_id: int, data: bytes,
                filename: str, how: Alignment, ignore_labels: list[str],
                user_id: int | None = None, mains_hz: int | None = None) -> EmgRecording:
    """Store the file's EMG as a recording of the session; ValueError (a 4xx) for a
    file, a montage or an alignment that does not fit. Nothing is stored on error."""
    montage = recordings.session_montage(db, session_id)
    edf, kind = read(data)
    signals = list(edf.signals)
    labels = [s.label for s in signals]
    cols = recordings.map_channels(montage, labels, ignore_labels)
    chosen = [signals[i] for i in cols]
    rates = {float(s.sampling_frequency) for s in chosen}
    if len(rates) != 1:
        raise ValueError(f"the montage's channels have different sampling rates {sorted(rates)}"
                         " Hz; one recording needs one rate")
    fs = rates.pop()
    factors = []
    for s in chosen:
        try:
            factors.append(recordings.volts_per_unit(s.physical_dimension))
        except ValueError as exc:
            raise ValueError(f"channel {s.label!r}: {exc}") from exc
    off, how_text = offset(db, session_id, edf, how)
    duration = float(edf.duration)

    def blocks() -> Iterator[Block]:
        start = 0.0
        while start < duration:
            stop = min(duration, start + BLOCK_S)
            x = np.column_stack([s.get_data_slice(start, stop) * f
                                 for s, f in zip(chosen, factors, strict=True)])
            yield None, x
            start = stop

    return recordings.store_blocks(db, settings, session_id, montage, kind, fs, blocks(), off,
                                   how_text, filename, user_id, mains_hz)
