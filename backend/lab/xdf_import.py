"""LabRecorder XDF files attached to a session, aligned with ExoStudy's own ticks.

pyxdf reads the file and maps every stream onto the recording computer's LSL clock with
the clock offsets LabRecorder stored (no de-jittering: the stamps stay as sent). When
LabRecorder ran on the ExoStudy machine, that clock is ours; when it ran elsewhere, the
ExoStudy tick stream inside the file gives the difference: its samples carry the device
sequence number, so each can be matched with the stored tick and its LSL time (the
tick's read time plus the clock offset recorded with the trial's start marker).
Every stream's span, moved onto our clock, is then compared with the trials' spans
(start to stop markers) to say which trials it covers.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import tick_queries
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.lab import xdf_limits
from backend.schemas.lab import XdfStreamSummary


def _first(info: dict[str, Any], key: str, default: str = "") -> str:
    v = info.get(key)
    if isinstance(v, list):
        return str(v[0]) if v and v[0] is not None else default
    return default if v is None else str(v)


def _channels(info: dict[str, Any]) -> list[str]:
    try:
        chans = info["desc"][0]["channels"][0]["channel"]
        return [_first(c, "label") for c in chans]
    except (KeyError, IndexError, TypeError):
        return []


def read(data: bytes) -> list[dict[str, Any]]:
    """The streams of an XDF file as pyxdf gives them; ValueError names the problem.

    The declared sizes are checked first (`xdf_limits.check`: nothing is allocated for a
    file that declares more than it holds), then pyxdf reads the checked bytes in a
    child process with a memory ceiling (`xdf_limits.load`).
    """
    plan = xdf_limits.check(data)
    streams = xdf_limits.load(data[:plan.readable_bytes])
    # pyxdf recovers what it can from a damaged file (a LabRecorder killed mid-write);
    # a file from which nothing can be recovered is refused.
    if not any(len(s.get("time_stamps", [])) for s in streams):
        raise ValueError("no stream in the XDF file holds samples (empty or damaged file)")
    return list(streams)


def _trial_spans(db: Session, session_id: int) -> dict[int, tuple[float, float, int, float]]:
    """trial id -> (LSL start, LSL stop, run id, LSL minus Unix time) from the trial's
    start and stop markers."""
    spans: dict[int, tuple[float, float, int, float]] = {}
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
                           else math.inf, run_id, math.nan)
    return spans


def _clock_of_run(engine: Engine, db: Session, trial_id: int, run_id: int
                  ) -> tuple[float, dict[int, float]]:
    """(LSL minus Unix offset, seq -> tick LSL time) of a trial's run."""
    start = db.scalar(select(Marker).where(Marker.trial_id == trial_id,
                                           Marker.label == "trial_start",
                                           Marker.source == "system"))
    cols = tick_queries.columns(engine, run_id)
    if start is None or start.t is None or start.lsl_time is None or cols["t"].size == 0:
        return math.nan, {}
    i = int(np.argmin(np.abs(cols["t"] - start.t)))
    offset = float(start.lsl_time - cols["t_host"][i])
    return offset, {int(s): float(h + offset)
                    for s, h in zip(cols["seq"], cols["t_host"], strict=True)}


def align(engine: Engine, db: Session, session_id: int, streams: list[dict[str, Any]]
          ) -> list[XdfStreamSummary]:
    """Summaries of the file's streams, on ExoStudy's LSL clock, with covered trials."""
    spans = _trial_spans(db, session_id)
    # Stored tick LSL times of every trial of the session, by sequence number.
    by_seq: dict[int, float] = {}
    for trial_id, (_, _, run_id, _) in spans.items():
        by_seq.update(_clock_of_run(engine, db, trial_id, run_id)[1])
    shift = 0.0  # file clock minus ExoStudy's clock
    own_offsets: dict[int, float] = {}
    for k, s in enumerate(streams):
        info = s["info"]
        labels = _channels(info)
        if _first(info, "type") == "ExoskeletonTicks" and "seq" in labels and by_seq:
            ts = np.asarray(s["time_stamps"], dtype=np.float64)
            seqs = np.asarray(s["time_series"], dtype=np.float64)[:, labels.index("seq")]
            diffs = [t - by_seq[int(q)] for q, t in zip(seqs, ts, strict=True)
                     if int(q) in by_seq]
            if diffs:
                own_offsets[k] = float(np.median(diffs))
    if own_offsets:
        shift = next(iter(own_offsets.values()))
    out = []
    for k, s in enumerate(streams):
        info = s["info"]
        ts = np.asarray(s["time_stamps"], dtype=np.float64)
        first = float(ts[0]) if ts.size else None
        last = float(ts[-1]) if ts.size else None
        covered = []
        if first is not None and last is not None:
            lo, hi = first - shift, last - shift
            covered = sorted(tid for tid, (a, b, _, _) in spans.items() if lo <= b and hi >= a)
        name = _first(info, "name")
        out.append(XdfStreamSummary(
            stream_id=int(_first(info, "stream_id", str(k)) or k), name=name,
            type=_first(info, "type"),
            channel_count=int(_first(info, "channel_count", "0") or 0),
            nominal_srate=float(_first(info, "nominal_srate", "0") or 0.0),
            samples=int(ts.size), first_time=first, last_time=last,
            channels=_channels(info),
            exostudy=_first(info, "type") in ("ExoskeletonTicks",) or name.startswith(
                "ExoStudy"),
            trial_ids=covered,
            offset_ms=own_offsets[k] * 1000.0 if k in own_offsets else None))
    return out
