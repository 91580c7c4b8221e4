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

A header that cannot describe EMG is a 422 naming the field and its value (`check`): a
rate outside `recordings.MIN_IMPORT_RATE_HZ`-`MAX_IMPORT_RATE_HZ`, a record duration
outside `RECORD_S_RANGE`, a physical or digital minimum equal to its maximum, a physical
range that is not finite. A file holding fewer records than its header says (a copy cut
short) is imported with what it holds and the flag `file_truncated` (the alignment text
says how many records were missing): the samples are real, the flag makes the loss
visible. An EDF+D/BDF+D file (discontinuous) keeps each record at its own onset (the
first time-keeping annotation of the record), so a pause is a gap in the timestamps
(flagged `dropped_samples` by the quality summary) with the flag `discontinuous_file`,
never samples joined across it.
"""

from __future__ import annotations

import io
import math
import re
import warnings
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
#: Record durations (s) a file of EMG may state: EDF records are commonly 0.1-1 s; a
#: duration outside this is a damaged header, not a recording.
RECORD_S_RANGE = (1e-3, 3600.0)
#: Flags of an imported file as a whole.
FILE_TRUNCATED = "file_truncated"
DISCONTINUOUS_FILE = "discontinuous_file"
#: A record's time-keeping annotation: its onset, then byte 20.
_ONSET = re.compile(rb"([+-]\d+(?:\.\d*)?)\x14")
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
    edf, kind, _missing = read_counted(data)
    return edf, kind


def read_counted(data: bytes) -> tuple[Any, str, int]:
    """`read`, and how many records the header promised that the file does not hold."""
    import edfio

    kind = "bdf" if data.startswith(BDF_MAGIC) else "edf"
    try:
        stated = int(data[236:244].decode("ascii").strip())
    except (UnicodeDecodeError, ValueError):
        stated = -1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the count below says what was missing
            edf = (edfio.read_bdf if kind == "bdf" else edfio.read_edf)(io.BytesIO(data))
    except Exception as exc:  # edfio raises ValueError, IndexError, UnicodeDecodeError ...
        raise ValueError(f"not a readable {kind.upper()} file: {exc}") from exc
    missing = max(0, stated - int(edf.num_data_records)) if stated >= 0 else 0
    return edf, kind, missing


def check(edf: Any, chosen: list[Any]) -> None:
    """ValueError naming the header field and its value when it cannot describe EMG."""
    d = float(edf.data_record_duration)
    if not (math.isfinite(d) and RECORD_S_RANGE[0] <= d <= RECORD_S_RANGE[1]):
        raise ValueError(f"record duration {d!r} s in the header is not plausible: it must "
                         f"be {RECORD_S_RANGE[0]:g} to {RECORD_S_RANGE[1]:g} s")
    for sig in chosen:
        where = f"channel {sig.label!r}"
        pmin, pmax = float(sig.physical_min), float(sig.physical_max)
        if not (math.isfinite(pmin) and math.isfinite(pmax)):
            raise ValueError(f"{where}: physical range {pmin!r} to {pmax!r} is not finite")
        if pmin == pmax:
            raise ValueError(f"{where}: physical minimum equals physical maximum ({pmin!r}): "
                             "the samples cannot be scaled")
        if int(sig.digital_min) == int(sig.digital_max):
            raise ValueError(f"{where}: digital minimum equals digital maximum "
                             f"({sig.digital_min}): the samples cannot be scaled")
        try:
            recordings.check_import_rate(float(sig.sampling_frequency))
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from exc


def record_onsets(data: bytes, edf: Any, kind: str) -> list[float] | None:
    """Each record's onset (s from the file's start) from an EDF+D/BDF+D file's
    time-keeping annotations; None for a continuous file. ValueError for a
    discontinuous file whose records do not all state their onset."""
    reserved = data[192:236].decode("ascii", "replace").strip().upper()
    if not reserved.startswith(("EDF+D", "BDF+D")):
        return None
    ns = int(data[252:256].decode("ascii").strip())
    labels = [data[256 + i * 16:256 + (i + 1) * 16].decode("ascii", "replace").strip()
              for i in range(ns)]
    base = 256 + ns * 216
    spr = [int(data[base + i * 8:base + (i + 1) * 8].decode("ascii").strip())
           for i in range(ns)]
    width = 3 if kind == "bdf" else 2
    ann = next((i for i, lb in enumerate(labels)
                if lb in ("EDF Annotations", "BDF Annotations")), None)
    if ann is None:
        raise ValueError(f"the file says {reserved[:5]} (discontinuous) but has no "
                         "annotation signal stating its records' onsets")
    head = int(data[184:192].decode("ascii").strip())
    rec_len = sum(spr) * width
    at = sum(spr[:ann]) * width
    onsets = []
    for r in range(int(edf.num_data_records)):
        start = head + r * rec_len + at
        m = _ONSET.match(data[start:start + spr[ann] * width])
        if m is None:
            raise ValueError(f"record {r} of the {reserved[:5]} file states no onset")
        onsets.append(float(m.group(1)))
    return onsets


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
    edf, kind, missing = read_counted(data)
    signals = list(edf.signals)
    labels = [s.label for s in signals]
    cols = recordings.map_channels(montage, labels, ignore_labels)
    chosen = [signals[i] for i in cols]
    rates = {float(s.sampling_frequency) for s in chosen}
    if len(rates) != 1:
        raise ValueError(f"the montage's channels have different sampling rates {sorted(rates)}"
                         " Hz; one recording needs one rate")
    fs = rates.pop()
    check(edf, chosen)
    onsets = record_onsets(data, edf, kind)
    factors = []
    for s in chosen:
        try:
            factors.append(recordings.volts_per_unit(s.physical_dimension))
        except ValueError as exc:
            raise ValueError(f"channel {s.label!r}: {exc}") from exc
    off, how_text = offset(db, session_id, edf, how)
    duration = float(edf.duration)
    record_s = float(edf.data_record_duration)
    flags = []
    if missing:
        flags.append(FILE_TRUNCATED)
        held = int(edf.num_data_records)
        how_text += (f"; the file holds {held} of the {held + missing} records its header "
                     f"states: {missing * record_s:g} s missing at its end")
    per_record = round(fs * record_s)
    gapped = onsets is not None and any(
        abs(o - r * record_s) > 0.5 / fs for r, o in enumerate(onsets))
    if gapped:
        flags.append(DISCONTINUOUS_FILE)
        how_text += "; discontinuous (EDF+D): each record at its own onset"

    def blocks() -> Iterator[Block]:
        start = 0.0
        while start < duration:
            stop = min(duration, start + BLOCK_S)
            x = np.column_stack([s.get_data_slice(start, stop) * f
                                 for s, f in zip(chosen, factors, strict=True)])
            t = None
            if gapped and onsets is not None:
                first = round(start * fs)
                idx = np.arange(first, first + x.shape[0])
                t = np.asarray(onsets)[idx // per_record] + (idx % per_record) / fs
            yield t, x
            start = stop

    return recordings.store_blocks(db, settings, session_id, montage, kind, fs, blocks(), off,
                                   how_text, filename, user_id, mains_hz, flags=flags)
