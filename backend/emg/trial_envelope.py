"""The trial page's EMG panel: the stored EMG's envelope over one trial, decimated for
display, with the trial's lifts and each lift's outcomes.

The envelope is the study's zero-phase chain (`controller.emg.processing.process`) over
the trial plus `PAD_S` on either side (so the filters' edge transients fall outside
the trial), in volts, not normalised (normalisation needs the MVC or task references of
the whole study; the panel shows what was measured). The values sent are every k-th
sample of the full-rate envelope, at most `points` of them: the envelope holds nothing
above its low-pass (6 Hz by default), so about 30 points a second or more draws it
faithfully; the lift outcomes (peak, mean, integral) come from the full-rate envelope,
so a peak between two drawn points is still counted.

A lift is measured only when the recording holds at least `COVERAGE_SHARE` (90 %) of the
samples its span asks for; otherwise it is listed with `no_emg` and how much was
covered, never measured on a few samples. The recording's own flags (stream_lost,
stopped_mid_trial decided from the trial's span now) come with the answer.

Memory: the trial is read once (float64, every channel), then filtered one channel at
a time and only the decimated values and the lifts' outcomes kept, so a long trial costs
about one copy of itself; `BUSY` bounds the calls computing at once (a caller beyond it
gets 503 with Retry-After), so viewers cannot starve the recording and control work.

Lifts are the trial's ground truth as the results use it (the simulation's truth
columns, else the experimenter's segments), placed on the session clock through the
trial's `trial_start` marker, which holds both the device time of the tick and the
session (LSL) clock.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.emg import ANALYSED_STATUSES, EmgMontage, EmgRecording
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.emg import recordings, store
from backend.emg.live import study_processing
from backend.emg.quality_summary import STOPPED_MID_TRIAL
from backend.schemas.emg import TrialEmgChannel, TrialEmgLift, TrialEmgOut
from controller.emg.outcomes import window_outcome
from controller.emg.processing import fill_non_finite, process

PAD_S = 1.0
DEFAULT_POINTS = 2000
#: Share of a lift's samples the recording must hold for the lift to be measured.
COVERAGE_SHARE = 0.9
#: Below this share of a measured lift's samples, it is flagged `samples_missing`.
COMPLETE_SHARE = 0.98
NO_EMG, SAMPLES_MISSING = "no_emg", "samples_missing"
#: Envelope computations at once (each holds a trial in memory); more answer 503.
MAX_CONCURRENT = 2
BUSY = threading.BoundedSemaphore(MAX_CONCURRENT)
RETRY_AFTER_S = 5


class NoTrialEmgError(ValueError):
    """The trial has no EMG to show (the message says why and what to do)."""


class StillRecordingError(NoTrialEmgError):
    """The trial's EMG is being recorded now; its envelope comes once it is finished."""


class EnvelopeBusyError(RuntimeError):
    """`MAX_CONCURRENT` envelopes are being computed: try again in a few seconds."""


def _marker(db: Session, trial_id: int, label: str) -> Marker | None:
    return db.scalars(select(Marker).where(
        Marker.trial_id == trial_id, Marker.label == label, Marker.source == "system",
        Marker.lsl_time.is_not(None)).order_by(Marker.id)).first()


def _recording(db: Session, trial: Trial, start: float, stop: float) -> EmgRecording:
    """The recording of the session (complete, or interrupted: `ANALYSED_STATUSES`) that
    overlaps the trial most."""
    rows = list(db.scalars(select(EmgRecording).where(
        EmgRecording.session_id == trial.session_id,
        EmgRecording.status.in_(ANALYSED_STATUSES))))
    best, overlap = None, 0.0
    for r in rows:
        if r.t_start is None or r.t_end is None:
            continue
        o = min(stop, r.t_end) - max(start, r.t_start)
        if o > overlap:
            best, overlap = r, o
    if best is None:
        live = [r for r in db.scalars(select(EmgRecording).where(
            EmgRecording.session_id == trial.session_id,
            EmgRecording.status == "recording"))]
        if live:
            raise StillRecordingError(
                f"trial {trial.id}: EMG recording {live[0].id} of session "
                f"{trial.session_id} is still recording; its envelope is shown once the "
                "recording finishes (unsubscribe the stream, or wait)")
        raise NoTrialEmgError(
            f"trial {trial.id} has no EMG: none of the {len(rows)} EMG recordings of session "
            f"{trial.session_id} covers it; subscribe an EMG stream before the trial runs "
            "or import the amplifier's EDF/BDF or XDF file")
    return best


def trial_envelope(engine: Engine, db: Session, settings: Settings, trial: Trial,
                   points: int = DEFAULT_POINTS) -> TrialEmgOut:
    """The panel's data; `NoTrialEmgError` when there is nothing to show,
    `EnvelopeBusyError` when `MAX_CONCURRENT` are being computed."""
    if not BUSY.acquire(blocking=False):
        raise EnvelopeBusyError(f"{MAX_CONCURRENT} EMG envelopes are being computed; "
                                f"try again in {RETRY_AFTER_S} s")
    try:
        return _trial_envelope(engine, db, settings, trial, points)
    finally:
        BUSY.release()


def _trial_envelope(engine: Engine, db: Session, settings: Settings, trial: Trial,
                    points: int) -> TrialEmgOut:
    from backend.analysis.results import ground_truth, trial_columns, trial_segments

    first = _marker(db, trial.id, "trial_start")
    if first is None or first.lsl_time is None:
        raise NoTrialEmgError(f"trial {trial.id} has not run: it has no start marker, so no "
                              "EMG can be placed on it")
    start = float(first.lsl_time)
    last = _marker(db, trial.id, "trial_stop")
    cols = trial_columns(engine, trial)
    tick_t = np.asarray(cols.float_("t"), dtype=np.float64) if len(cols) else np.zeros(0)
    t_ref = float(first.t) if first.t is not None else (float(tick_t[0]) if tick_t.size
                                                         else 0.0)
    if last is not None and last.lsl_time is not None:
        stop = float(last.lsl_time)
    elif tick_t.size:
        stop = start + float(tick_t[-1] - t_ref)
    else:
        raise NoTrialEmgError(f"trial {trial.id} has no stop marker and no ticks: its span "
                              "is unknown")
    rec = _recording(db, trial, start, stop)
    montage = db.get(EmgMontage, rec.montage_id)
    assert montage is not None
    proc = study_processing(db, trial.session_id)
    off = rec.time_offset_s
    t, x = store.read_window(store.recording_path(settings, rec.id), start - PAD_S - off,
                             stop + PAD_S - off)
    if t.size < 2:
        raise NoTrialEmgError(f"trial {trial.id} has no EMG: recording {rec.id} holds no "
                              "samples inside the trial")
    rel = t + off - start  # seconds from the trial's start
    del t
    inside = np.flatnonzero((rel >= 0.0) & (rel <= stop - start))
    if inside.size < 2:
        raise NoTrialEmgError(f"trial {trial.id} has no EMG: recording {rec.id} ends before "
                              "the trial starts or starts after it ends")
    i0, i1 = int(inside[0]), int(inside[-1]) + 1
    step = max(1, math.ceil((i1 - i0) / max(points, 2)))
    shown = np.arange(i0, i1, step)
    truth = ground_truth(cols, trial.task, trial_segments(db, trial.id))
    windows = []  # per lift: index, kind, start_s, end_s, sample window or None, flags
    for lift in truth.lifts:
        if lift.end >= tick_t.size:
            continue
        a = float(tick_t[lift.start] - t_ref)
        b = float(tick_t[lift.end] - t_ref)
        win, lflags = _lift_window(rel, rec.fs, a, b)
        windows.append((lift.index, str(lift.kind), a, b, win, lflags))
    n_ch = len(montage.channels)
    values = np.empty((shown.size, n_ch))
    outcomes: dict[int, list[Any]] = {k: [] for k in range(len(windows))}
    for k in range(n_ch):  # one channel's envelope in memory at a time
        col, _ = fill_non_finite(x[:, k:k + 1])  # counted in the recording's flags
        try:
            env = process(col, rec.fs, proc)
        except ValueError as exc:
            raise NoTrialEmgError(f"trial {trial.id}: the EMG inside it cannot be "
                                  f"processed ({exc})") from exc
        del col
        values[:, k] = env[shown, 0]
        for w, (*_, win, _flags) in enumerate(windows):
            if win is not None:
                outcomes[w].append(window_outcome(env, rec.fs, win))
        del env
    del x
    chan_flags: dict[str, Any] = dict(rec.quality.get("channels", {})) if rec.quality else {}
    channels = [TrialEmgChannel(label=c["label"], muscle=c["muscle"], side=c["side"],
                                values=[float(v) for v in values[:, k]],
                                flags=sorted(chan_flags.get(c["label"], {})))
                for k, c in enumerate(montage.channels)]
    lifts = []
    for w, (index, kind, a, b, _win, lflags) in enumerate(windows):
        outs = outcomes[w]
        lifts.append(TrialEmgLift(
            index=index, kind=kind, start_s=a, end_s=b, flags=lflags,
            peak=[o.peak[0] for o in outs], mean=[o.mean[0] for o in outs],
            iemg=[o.iemg[0] for o in outs]))
    return TrialEmgOut(
        flags=_trial_flags(db, trial, rec),
        trial_id=trial.id, recording_id=rec.id, source=rec.source, processing=proc.to_dict(),
        recording_fs=rec.fs, fs=rec.fs / step, t=[float(v) for v in rel[shown]],
        duration_s=stop - start, channels=channels, lifts=lifts, lift_source=truth.source,
        lift_note=truth.note)


def _lift_window(rel: np.ndarray, fs: float, a: float, b: float
                 ) -> tuple[tuple[int, int] | None, list[str]]:
    """The lift's sample window (seconds from the trial's start a..b) and its flags:
    None and `no_emg:<coverage>` when the recording holds under `COVERAGE_SHARE` of the
    samples the lift's span asks for."""
    j0 = int(np.searchsorted(rel, a))
    j1 = int(np.searchsorted(rel, b, side="right"))
    expected = max(1.0, (b - a) * fs)
    share = (j1 - j0) / expected
    if j1 - j0 < 2 or share < COVERAGE_SHARE:
        return None, [f"{NO_EMG}:{min(share, 1.0):.0%} of the lift's samples"]
    if share < COMPLETE_SHARE:
        return (j0, j1), [f"{SAMPLES_MISSING}:{1 - share:.0%}"]
    return (j0, j1), []


def _trial_flags(db: Session, trial: Trial, rec: EmgRecording) -> list[str]:
    """The recording's flags that concern the whole trial (not its channels'), with
    `stopped_mid_trial` decided from the trial's span now."""
    q = rec.quality or {}
    chan = {f for per in (q.get("channels") or {}).values() for f in per}
    flags = [f for f in q.get("flags", []) if f not in chan and f != STOPPED_MID_TRIAL]
    span = next((s for s in recordings.trial_spans(db, trial.session_id)
                 if s["trial_id"] == trial.id), None)
    if span is not None and recordings.stopped_inside(rec.t_start, rec.t_end, span):
        flags.append(STOPPED_MID_TRIAL)
    return flags
