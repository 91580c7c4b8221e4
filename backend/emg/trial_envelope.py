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

Lifts are the trial's ground truth as the results use it (the simulation's truth
columns, else the experimenter's segments), placed on the session clock through the
trial's `trial_start` marker, which holds both the device time of the tick and the
session (LSL) clock.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.emg import EmgMontage, EmgRecording
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.emg import store
from backend.emg.live import study_processing
from backend.schemas.emg import TrialEmgChannel, TrialEmgLift, TrialEmgOut
from controller.emg.outcomes import window_outcome
from controller.emg.processing import fill_non_finite, process

PAD_S = 1.0
DEFAULT_POINTS = 2000


class NoTrialEmgError(ValueError):
    """The trial has no EMG to show (the message says why and what to do)."""


def _marker(db: Session, trial_id: int, label: str) -> Marker | None:
    return db.scalars(select(Marker).where(
        Marker.trial_id == trial_id, Marker.label == label, Marker.source == "system",
        Marker.lsl_time.is_not(None)).order_by(Marker.id)).first()


def _recording(db: Session, trial: Trial, start: float, stop: float) -> EmgRecording:
    """The complete recording of the session that overlaps the trial most."""
    rows = list(db.scalars(select(EmgRecording).where(
        EmgRecording.session_id == trial.session_id, EmgRecording.status == "complete")))
    best, overlap = None, 0.0
    for r in rows:
        if r.t_start is None or r.t_end is None:
            continue
        o = min(stop, r.t_end) - max(start, r.t_start)
        if o > overlap:
            best, overlap = r, o
    if best is None:
        raise NoTrialEmgError(
            f"trial {trial.id} has no EMG: none of the {len(rows)} EMG recordings of session "
            f"{trial.session_id} covers it; subscribe an EMG stream before the trial runs "
            "or import the amplifier's EDF/BDF or XDF file")
    return best


def trial_envelope(engine: Engine, db: Session, settings: Settings, trial: Trial,
                   points: int = DEFAULT_POINTS) -> TrialEmgOut:
    """The panel's data; `NoTrialEmgError` when there is nothing to show."""
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
    x, _ = fill_non_finite(x)  # counted in the recording's flags; shown there
    try:
        env = process(x, rec.fs, proc)
    except ValueError as exc:
        raise NoTrialEmgError(f"trial {trial.id}: the EMG inside it is too short to "
                              f"process ({exc})") from exc
    rel = t + off - start  # seconds from the trial's start
    inside = np.flatnonzero((rel >= 0.0) & (rel <= stop - start))
    if inside.size < 2:
        raise NoTrialEmgError(f"trial {trial.id} has no EMG: recording {rec.id} ends before "
                              "the trial starts or starts after it ends")
    i0, i1 = int(inside[0]), int(inside[-1]) + 1
    step = max(1, math.ceil((i1 - i0) / max(points, 2)))
    shown = np.arange(i0, i1, step)
    flags: dict[str, Any] = dict(rec.quality.get("channels", {})) if rec.quality else {}
    channels = [TrialEmgChannel(label=c["label"], muscle=c["muscle"], side=c["side"],
                                values=[float(v) for v in env[shown, k]],
                                flags=sorted(flags.get(c["label"], {})))
                for k, c in enumerate(montage.channels)]
    truth = ground_truth(cols, trial.task, trial_segments(db, trial.id))
    lifts = []
    for lift in truth.lifts:
        if lift.end >= tick_t.size:
            continue
        a = start + float(tick_t[lift.start] - t_ref)
        b = start + float(tick_t[lift.end] - t_ref)
        j0 = int(np.searchsorted(rel, a - start))
        j1 = int(np.searchsorted(rel, b - start, side="right"))
        if j1 - j0 < 2:
            continue  # the lift lies outside the recording
        out = window_outcome(env, rec.fs, (j0, j1))
        lifts.append(TrialEmgLift(index=lift.index, kind=str(lift.kind), start_s=a - start,
                                  end_s=b - start, peak=list(out.peak), mean=list(out.mean),
                                  iemg=list(out.iemg)))
    return TrialEmgOut(
        trial_id=trial.id, recording_id=rec.id, source=rec.source, processing=proc.to_dict(),
        recording_fs=rec.fs, fs=rec.fs / step, t=[float(v) for v in rel[shown]],
        duration_s=stop - start, channels=channels, lifts=lifts, lift_source=truth.source,
        lift_note=truth.note)
