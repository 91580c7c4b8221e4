"""LabRecorder XDF files attached to a session, aligned with ExoStudy's own ticks.

The file is read by ExoStudy's own bounded reader in a child process
(`backend/lab/xdf_child.py`): every stream is mapped onto the recording computer's LSL
clock with the clock offsets LabRecorder stored (no de-jittering: the stamps stay as
sent), and only a summary and the tick stream's (time, seq) columns come back. When
LabRecorder ran on the ExoStudy machine, that clock is ours; when it ran elsewhere, the
ExoStudy tick stream inside the file gives the difference: its samples carry the device
sequence number, so each can be matched with the stored tick and its LSL time (the
tick's read time plus the clock offset recorded with the trial's start marker).
Every stream's span, moved onto our clock, is then compared with the trials' spans
(start to stop markers) to say which trials it covers.

What is stored passes one check first (`storable`): every number in it finite, and the
whole within `xdf_max_summary_bytes`, so the JSON column holds standard JSON on SQLite
and PostgreSQL and a listing of a session's files stays small (issue 28: an offset of
1.7e308 s stored as Infinity; 25 MB of channel labels stored per file).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.core.config import Settings
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.lab import xdf_child
from backend.lab.xdf_child import ParsedStream
from backend.lab.xdf_reader import XdfError, XdfLimits
from backend.schemas.lab import XdfStreamSummary

#: Rows of a tick stream's columns read from disk at a time (4 MB).
_BLOCK_ROWS = 262_144


def limits(settings: Settings) -> XdfLimits:
    """The reader's limits from the server's settings."""
    return XdfLimits(max_streams=settings.xdf_max_streams,
                     max_chunks=settings.xdf_max_chunks,
                     max_samples=settings.xdf_max_samples,
                     max_clock_offsets=settings.xdf_max_clock_offsets,
                     max_decoded_bytes=settings.xdf_max_decoded_bytes,
                     max_channels=settings.xdf_max_channels,
                     max_header_bytes=settings.xdf_max_header_bytes)


def import_file(engine: Engine, db: Session, session_id: int, data: bytes,
                settings: Settings) -> list[dict[str, Any]]:
    """The aligned summary of the XDF file `data` for the session, as it is stored;
    `XdfError` (a ValueError) says what is wrong with the file."""
    with xdf_child.parsed(data, limits(settings), settings.xdf_work_dir,
                          settings.xdf_parse_seconds, settings.xdf_summary_channels
                          ) as streams:
        # A file cut short early (a LabRecorder killed mid-write) may hold headers only.
        if not any(s.samples for s in streams):
            raise XdfError("no stream in the XDF file holds samples (empty or damaged file)")
        return storable(align(engine, db, session_id, streams),
                        settings.xdf_max_summary_bytes)


def _numbers(value: Any) -> Iterator[float]:
    """The floats in a summary's value (lists opened)."""
    if isinstance(value, float):
        yield value
    elif isinstance(value, list | tuple):
        for item in value:
            yield from _numbers(item)


def storable(summary: list[XdfStreamSummary], max_bytes: int) -> list[dict[str, Any]]:
    """The summary as stored, after the one check at the storage boundary: XdfError
    unless every number in it is finite and its JSON takes at most `max_bytes`."""
    rows = [s.model_dump() for s in summary]
    for row in rows:
        for key, value in row.items():
            bad = next((x for x in _numbers(value) if not math.isfinite(x)), None)
            if bad is not None:
                raise XdfError(f"stream {row['stream_id']}: {key} is {bad}, not a finite "
                               "number; nothing of the file was stored")
    size = len(json.dumps(rows, allow_nan=False))
    if size > max_bytes:
        raise XdfError(f"the summary of the file's {len(rows)} streams takes {size} bytes, "
                       f"more than {max_bytes} bytes (the server's xdf_max_summary_bytes)")
    return rows


def _trial_spans(db: Session, session_id: int) -> dict[int, tuple[float, float, int]]:
    """trial id -> (LSL start, LSL stop, run id) from the trial's start and stop
    markers."""
    spans: dict[int, tuple[float, float, int]] = {}
    rows = db.execute(select(Trial.id, Trial.run_id).where(Trial.session_id == session_id,
                                                           Trial.run_id.is_not(None)))
    for trial_id, run_id in rows:
        if run_id is None:
            continue
        ms = {m.label: m for m in db.scalars(select(Marker).where(
            Marker.trial_id == trial_id, Marker.source == "system",
            Marker.label.in_(("trial_start", "trial_stop"))))}
        start, stop = ms.get("trial_start"), ms.get("trial_stop")
        if start is None or start.lsl_time is None:
            continue
        spans[trial_id] = (start.lsl_time,
                           stop.lsl_time if stop is not None and stop.lsl_time is not None
                           else math.inf, run_id)
    return spans


def _clock_of_run(engine: Engine, db: Session, trial_id: int, run_id: int
                  ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """(seq, LSL time) of the ticks of a trial's run."""
    start = db.scalar(select(Marker).where(Marker.trial_id == trial_id,
                                           Marker.label == "trial_start",
                                           Marker.source == "system"))
    cols = tick_queries.columns(engine, run_id, fields=("seq", "t", "t_host"))
    if start is None or start.t is None or start.lsl_time is None or cols["t"].size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    i = int(np.argmin(np.abs(cols["t"] - start.t)))
    offset = float(start.lsl_time - cols["t_host"][i])
    lsl = cols["t_host"].astype(np.float64) + offset
    keep = np.isfinite(lsl)
    return cols["seq"].astype(np.int64)[keep], lsl[keep]


def _stored_ticks(engine: Engine, db: Session, spans: dict[int, tuple[float, float, int]]
                  ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Stored ticks of the session's trials as (seq, LSL time), sorted by seq; of ticks
    sharing a seq, the later trial's."""
    parts = [_clock_of_run(engine, db, trial_id, run_id)
             for trial_id, (_, _, run_id) in spans.items()]
    seq = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, dtype=np.int64)
    lsl = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0)
    # The last occurrence of each seq: the first in the reversed order.
    unique, first_of_reversed = np.unique(seq[::-1], return_index=True)
    return unique, lsl[::-1][first_of_reversed]


def _tick_offset(path: Path, seq: NDArray[np.int64], lsl: NDArray[np.float64]
                 ) -> float | None:
    """Median of (file time - stored LSL time) over the stored ticks the file's tick
    stream holds, read from disk a block at a time; None if none match. Memory is
    bounded by the stored ticks, however many samples the file repeats."""
    cols = np.load(path, mmap_mode="r", allow_pickle=False)
    if cols.ndim != 2 or cols.shape[1] != 2 or seq.size == 0:
        return None
    diff = np.full(seq.size, np.nan)
    for lo in range(0, cols.shape[0], _BLOCK_ROWS):
        block = np.asarray(cols[lo:lo + _BLOCK_ROWS])
        q = block[:, 1].astype(np.int64)
        at = np.minimum(np.searchsorted(seq, q), seq.size - 1)
        hit = seq[at] == q
        diff[at[hit]] = block[hit, 0] - lsl[at[hit]]
    found = diff[np.isfinite(diff)]
    return float(np.median(found)) if found.size else None


def clock_shift(engine: Engine, db: Session, session_id: int, streams: list[ParsedStream]
                ) -> float | None:
    """The file's clock minus ExoStudy's LSL clock, from the first tick stream whose
    samples match stored ticks of the session; None when none does."""
    seq, lsl = _stored_ticks(engine, db, _trial_spans(db, session_id))
    for s in streams:
        if s.ticks is not None:
            offset = _tick_offset(s.ticks, seq, lsl)
            if offset is not None:
                return offset
    return None


def align(engine: Engine, db: Session, session_id: int, streams: list[ParsedStream]
          ) -> list[XdfStreamSummary]:
    """Summaries of the file's streams, on ExoStudy's LSL clock, with covered trials."""
    spans = _trial_spans(db, session_id)
    seq, lsl = _stored_ticks(engine, db, spans)
    own_offsets: dict[int, float] = {}
    for k, s in enumerate(streams):
        if s.ticks is not None:
            offset = _tick_offset(s.ticks, seq, lsl)
            if offset is not None:
                own_offsets[k] = offset
    shift = next(iter(own_offsets.values()), 0.0)  # file clock minus ExoStudy's clock
    out = []
    for k, s in enumerate(streams):
        covered: list[int] = []
        if s.first_time is not None and s.last_time is not None:
            lo = min(s.first_time, s.last_time) - shift
            hi = max(s.first_time, s.last_time) - shift
            covered = sorted(tid for tid, (a, b, _) in spans.items() if lo <= b and hi >= a)
        out.append(XdfStreamSummary(
            stream_id=s.stream_id, name=s.name, type=s.type,
            channel_count=s.channel_count, nominal_srate=s.nominal_srate,
            samples=s.samples, first_time=s.first_time, last_time=s.last_time,
            channels=s.channels, labelled_channels=s.labelled_channels,
            exostudy=s.type == xdf_child.TICK_STREAM_TYPE or s.name.startswith("ExoStudy"),
            trial_ids=covered,
            offset_ms=own_offsets[k] * 1000.0 if k in own_offsets else None))
    return out

