"""Muscle activity in a study's results: per-lift EMG outcomes from the STORED recordings,
and per controller the mean over participants, the reduction against each baseline and
repeated-measures statistics.

Per completed trial of a counted participant:

1. **Lifts.** The trial's lifts as the other results find them (`results.ground_truth`:
   the simulation's truth, else the experimenter's segments); a trial without ticks (a
   "no exoskeleton" baseline in a lab, the device off) takes its lifts from the
   experimenter's `lift_start`/`lift_stop` console markers, `note` = the lift kind.
2. **Times.** A tick's instant on the session clock is the trial's `trial_start`
   marker (stamped at the run's first tick) plus the tick's host time since that tick
   (`t_host`, the instant the worker read it, which is what LSL stamps too); device time
   where host times are missing. EMG timestamps plus the recording's `time_offset_s`
   are on the same clock.
3. **Envelope.** The session's complete recordings covering the trial are read over the
   trial's span (plus `PAD_S` either side, so the zero-phase filters settle before the
   first lift) and processed with the study's saved `EmgProcessing`. A lift is measured
   in the recording that covers all of it; a lift no recording covers (a stream that
   stopped or restarted inside it) is listed with the flag `no_emg` and no numbers.
4. **Outcomes** (`controller.emg.outcomes`): per lift and channel the peak, mean and
   iEMG of the envelope over the lift and its two halves (lowering, lifting) and the
   envelope over the normalised lift cycle, first in volts, then divided by the
   session's reference: `mvc` (the largest 0.5 s average over the session's MVC
   repetitions), `task_peak` or `task_mean` (over every lift of the session, all
   conditions, so a condition's level is comparable with another's). A session
   whose MVC misses a channel is reported in volts (`none`) with the flag `no_mvc`;
   task activity above the MVC is flagged `exceeds_mvc` with its ratio and kept.
5. **Aggregates** (`controller.evaluation.muscle_stats`): per participant and condition
   the mean over their lifts; per condition the mean over participants with its 95 %
   interval; the reduction against each baseline planned (one-sample t on the per-
   participant reductions, Holm-corrected); the Friedman test across conditions.

Quality flags of the recordings (clipping, flat line, mains, motion, dropped samples,
rate, a stream lost, restarted or stopped mid-trial) travel with each trial and lift:
flagged data are kept and shown, never dropped.
"""

from __future__ import annotations

import io
import json
import math
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import results, results_cache
from backend.db.emg import ANALYSED_STATUSES, EmgAnalysisSettings, EmgMontage, EmgRecording
from backend.db.evidence_tables import Trial
from backend.db.lab import Marker
from backend.db.models import Participant, StudySession
from backend.emg import mvc, recordings, store
from backend.emg.quality_summary import STOPPED_MID_TRIAL
from controller import spreadsheet
from controller.controllers import registry
from controller.controllers.baselines import NO_EXOSKELETON
from controller.device.base import SAMPLE_PERIOD_S
from controller.emg import quality
from controller.emg.normalisation import UNITS, moving_average_max, mvc_reference
from controller.emg.outcomes import CYCLE_POINTS, LiftOutcome, lift_outcome
from controller.emg.processing import EmgProcessing, EmgSettingsError, fill_non_finite, process
from controller.evaluation import muscle_stats
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import LIFT_KINDS
from controller.evaluation.study import condition_controller, condition_rank

if TYPE_CHECKING:
    from controller.evaluation.rendering import RenderedFigure

#: Seconds of EMG read either side of a trial or an MVC repetition: the zero-phase
#: filters' start-up transient (a 6 Hz 4th-order low-pass settles within about 0.5 s)
#: stays outside the windows measured.
PAD_S = 1.0
#: The normalisation method that keeps volts (the envelopes are not divided).
VOLTS = "none"
#: Outcome measures per lift and channel.
METRICS = ("peak", "mean", "iemg")
#: Groups of lifts the aggregates are given for: every lift, then each kind.
GROUPS: tuple[str, ...] = ("all", *LIFT_KINDS)
#: Console markers that bound a lift of a trial without ticks.
LIFT_START, LIFT_STOP = "lift_start", "lift_stop"
#: Flags this module adds (the recordings' own flags are `controller.emg.quality`'s and
#: `backend.emg.quality_summary`'s).
NO_EMG = "no_emg"
NO_MVC = "no_mvc"
EXCEEDS_MVC = "exceeds_mvc"
NON_FINITE_FILLED = "non_finite_filled"
SAMPLES_MISSING = "samples_missing"
#: The recording's file does not read back past some point inside the trial (a damaged
#: chunk): the lifts after it have no EMG; every other trial is measured as usual.
FILE_DAMAGED = "file_damaged"
#: A lift's window must hold this share of the samples its duration asks for (fewer: the
#: stream lost samples there, flagged `samples_missing`), and half of them to be measured
#: at all (fewer: `no_emg`).
COMPLETE_SHARE, MEASURED_SHARE = 0.98, 0.5


@dataclass
class LiftEmg:
    """One lift's outcomes per channel, in volts until `normalise` divides them."""

    index: int
    kind: str
    t_start: float
    t_end: float
    recording_id: int | None
    outcome: LiftOutcome | None
    #: Per channel the largest `mvc_window_s` average over the lift (volts), for the
    #: check against the MVC.
    peak_average: tuple[float, ...] = ()
    flags: list[str] = field(default_factory=list)


@dataclass
class TrialEmg:
    """One trial's EMG: its lifts, the recordings used and what is wrong with them."""

    trial_id: int
    session_id: int
    participant: str
    condition: str
    task: str
    lift_source: str
    recordings: list[int] = field(default_factory=list)
    lifts: list[LiftEmg] = field(default_factory=list)
    flags: list[str] = field(default_factory=list)
    channel_flags: dict[str, list[str]] = field(default_factory=dict)
    note: str = ""


@dataclass
class SessionReference:
    """What a session's envelopes are divided by."""

    method: str
    values: tuple[float, ...]
    flags: list[str] = field(default_factory=list)
    exceeds: dict[str, float] = field(default_factory=dict)

    @property
    def unit(self) -> str:
        return UNITS.get(self.method, "V")


@dataclass
class MuscleResults:
    """Every trial's muscle activity and the study's aggregates."""

    study_id: int
    processing: dict[str, Any]
    mains_hz: int
    channels: list[str] = field(default_factory=list)
    trials: list[TrialEmg] = field(default_factory=list)
    references: dict[int, SessionReference] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    # ------------------------------------------------------------------ rows

    def conditions(self) -> list[str]:
        """Conditions present, in the registry's display order, a controller's variants
        (personal models, learned priors) after its plain name."""
        present = {t.condition for t in self.trials if any(lf.outcome for lf in t.lifts)}
        order = list(registry.display_order())

        def rank(c: str) -> tuple[int, int, str]:
            base = condition_controller(c)
            return (order.index(base) if base in order else len(order), condition_rank(c), c)
        return sorted(present, key=rank)

    def baselines(self) -> list[str]:
        """The baseline conditions with data."""
        return [c for c in registry.baselines() if c in self.conditions()]

    def outcome_rows(self, metric: str = "mean", group: str = "all"
                     ) -> list[muscle_stats.OutcomeRow]:
        """Per participant, condition and channel: the mean over their lifts of `group`."""
        if metric not in METRICS:
            raise results.ResultsError("metric", f"choose one of {', '.join(METRICS)}")
        acc: dict[tuple[str, str, str], list[float]] = defaultdict(list)
        for t in self.trials:
            for lf in t.lifts:
                if lf.outcome is None or (group != "all" and lf.kind != group):
                    continue
                values = getattr(lf.outcome.lift, metric)
                for ch, v in zip(self.channels, values, strict=True):
                    acc[(t.participant, t.condition, ch)].append(float(v))
        return [muscle_stats.OutcomeRow(p, c, ch, float(np.mean(v)))
                for (p, c, ch), v in sorted(acc.items())]

    def summary(self) -> list[dict[str, Any]]:
        """Per group, metric, condition and channel: the mean over participants with its
        95 % t interval."""
        out: list[dict[str, Any]] = []
        for group in GROUPS:
            for metric in METRICS:
                by: dict[tuple[str, str], list[float]] = defaultdict(list)
                for r in self.outcome_rows(metric, group):
                    by[(r.condition, r.channel)].append(r.value)
                for (cond, ch), v in sorted(by.items()):
                    mean, lo, hi, _ = muscle_stats.mean_t_interval(v)
                    out.append({"group": group, "metric": metric, "condition": cond,
                                "channel": ch, "n": len(v), "mean": _num(mean),
                                "ci_low": _num(lo), "ci_high": _num(hi),
                                "unit": self.unit(metric)})
        return out

    def unit(self, metric: str) -> str:
        """The unit of a metric's values (mixed if sessions were normalised differently)."""
        units = {r.unit for r in self.references.values()}
        base = units.pop() if len(units) == 1 else "mixed units (see references)"
        return f"{base} x s" if metric == "iemg" else base

    def reductions(self) -> list[dict[str, Any]]:
        """Each condition against each baseline, per group, metric and channel."""
        return self._reductions()[0]

    def reduction_gaps(self) -> list[dict[str, Any]]:
        """The baseline x group x metric families without reductions, and why (a baseline
        trial may hold only some lift kinds: that group has no baseline data)."""
        return self._reductions()[1]

    def _reductions(self, groups: Sequence[str] = GROUPS, metrics: Sequence[str] = METRICS
                    ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        """Reductions and gaps of the `groups` x `metrics` families (default: all); a
        family the statistics refuse becomes a stated gap, never an error for the whole
        study. Each family is computed on its own, so asking for fewer changes none."""
        out: list[dict[str, Any]] = []
        gaps: list[dict[str, Any]] = []
        for baseline in self.baselines():
            for group in groups:
                for metric in metrics:
                    rows = self.outcome_rows(metric, group)
                    if not rows:
                        continue
                    gap = {"baseline": baseline, "group": group, "metric": metric}
                    if not any(r.condition == baseline for r in rows):
                        gaps.append({**gap, "gap": f"no baseline data: no {group} lift "
                                     f"of {baseline!r} has EMG"})
                        continue
                    try:
                        reds = muscle_stats.reductions(rows, baseline)
                    except ValueError as exc:
                        gaps.append({**gap, "gap": str(exc)})
                        continue
                    for red in reds:
                        out.append({"group": group, "metric": metric, **red.to_dict()})
        return out, gaps

    def repeated(self) -> list[dict[str, Any]]:
        """Friedman across all conditions per channel, for every lift, per metric."""
        out: list[dict[str, Any]] = []
        for metric in METRICS:
            rows = self.outcome_rows(metric, "all")
            if len({r.condition for r in rows}) < 2:
                continue
            for rm in muscle_stats.repeated_measures(rows):
                out.append({"group": "all", "metric": metric, **rm.to_dict()})
        return out

    def cycles(self, group: str = "all") -> dict[str, dict[str, Any]]:
        """Per condition and channel, the normalised lift cycle: the mean over
        participants of each participant's mean cycle, and the band (mean +- 1 SD)."""
        per: dict[tuple[str, str], list[NDArray[np.float64]]] = defaultdict(list)
        for t in self.trials:
            for lf in t.lifts:
                if lf.outcome is None or (group != "all" and lf.kind != group):
                    continue
                per[(t.participant, t.condition)].append(lf.outcome.cycle)
        out: dict[str, dict[str, Any]] = {}
        for cond in self.conditions():
            means = [np.mean(v, axis=0) for (p, c), v in sorted(per.items()) if c == cond]
            if not means:
                continue
            stack = np.stack(means)  # participants x points x channels
            out[cond] = {"n": len(means), "mean": stack.mean(axis=0),
                         "sd": stack.std(axis=0, ddof=1) if len(means) > 1
                         else np.zeros_like(stack[0])}
        return out

    def lift_rows(self) -> tuple[list[str], list[list[Any]]]:
        """One row per lift and channel (the long CSV)."""
        header = ["trial_id", "participant", "condition", "task", "lift", "kind",
                  "lift_source", "recording_id", "t_start", "t_end", "channel",
                  "normalisation", "unit", "peak", "mean", "iemg", "peak_lowering",
                  "mean_lowering", "peak_lifting", "mean_lifting", "flags"]
        rows: list[list[Any]] = []
        for t in self.trials:
            ref = self.references.get(t.session_id)
            method = ref.method if ref else ""
            unit = ref.unit if ref else ""
            if not t.lifts:
                rows.append([t.trial_id, t.participant, t.condition, t.task, "", "",
                             t.lift_source, "", "", "", "", method, unit, "", "", "", "",
                             "", "", "", ";".join(t.flags)])
            for lf in t.lifts:
                for c, ch in enumerate(self.channels):
                    flags = [*t.flags, *t.channel_flags.get(ch, []), *lf.flags,
                             *([f"{EXCEEDS_MVC}:{ref.exceeds[ch]:.2f}"]
                               if ref is not None and ch in ref.exceeds else [])]
                    o = lf.outcome
                    ph = o.phases if o is not None else {}
                    rows.append([
                        t.trial_id, t.participant, t.condition, t.task, lf.index, lf.kind,
                        t.lift_source, lf.recording_id, round(lf.t_start, 4),
                        round(lf.t_end, 4), ch, method, unit,
                        *([_num(o.lift.peak[c]), _num(o.lift.mean[c]), _num(o.lift.iemg[c])]
                          if o is not None else ["", "", ""]),
                        *[_num(getattr(ph[p], m)[c]) if p in ph else ""
                          for p in ("lowering", "lifting") for m in ("peak", "mean")],
                        ";".join(dict.fromkeys(flags))])
        return header, rows

    # ------------------------------------------------------------------ outputs

    def method(self) -> dict[str, Any]:
        """Everything a reader needs to reproduce the numbers."""
        return {
            "processing": self.processing, "mains_hz": self.mains_hz,
            "normalisation": self.processing.get("normalisation"),
            "normalisation_reference": (
                "mvc: largest mvc_window_s moving average of the envelope over the "
                "session's MVC repetitions; task_peak / task_mean: over every lift of the "
                "session, all conditions"),
            "pad_s": PAD_S, "cycle_points": CYCLE_POINTS,
            "phases": {"lowering": "onset to the lift's midpoint",
                       "lifting": "midpoint to the return to standing"},
            "participant_value": "mean over the participant's lifts",
            "interval": "95 % Student t interval of the mean over participants",
            "reduction": "100 x (1 - condition / baseline) per participant; "
                         + muscle_stats.REDUCTION_TEST + ", Holm-corrected over each "
                         "baseline x group x metric family",
            "repeated_measures": muscle_stats.REPEATED_TEST,
            "lift_times": "trial_start marker + tick host time since the first tick",
        }

    def document(self) -> dict[str, Any]:
        """The JSON body of `GET /api/studies/{id}/muscle-results`."""
        return {
            "study_id": self.study_id, "method": self.method(), "channels": self.channels,
            "conditions": self.conditions(), "baselines": self.baselines(),
            "references": {str(k): {"method": v.method, "unit": v.unit,
                                    "values": [_num(x) for x in v.values],
                                    "flags": v.flags, "exceeds_mvc": v.exceeds}
                           for k, v in self.references.items()},
            "trials": [{"trial_id": t.trial_id, "participant": t.participant,
                        "condition": t.condition, "task": t.task,
                        "lift_source": t.lift_source, "recordings": t.recordings,
                        "lifts": sum(1 for lf in t.lifts if lf.outcome is not None),
                        "lifts_without_emg": sum(1 for lf in t.lifts if lf.outcome is None),
                        "flags": t.flags, "channel_flags": t.channel_flags, "note": t.note}
                       for t in self.trials],
            "summary": self.summary(), "reductions": self.reductions(),
            "reduction_gaps": self.reduction_gaps(),
            "repeated_measures": self.repeated(), "notes": self.notes,
        }

    def csv(self, name: str) -> str:
        """`lifts`, `summary`, `reductions` or `repeated_measures` as CSV; the method
        (every processing parameter) in the first comment lines."""
        if name == "lifts":
            header, rows = self.lift_rows()
        elif name in ("summary", "reductions", "repeated_measures"):
            dicts = {"summary": self.summary, "reductions": self.reductions,
                     "repeated_measures": self.repeated}[name]()
            header = list(dicts[0]) if dicts else ["group", "metric"]
            rows = [[_cell(d.get(k)) for k in header] for d in dicts]
        else:
            raise results.ResultsError("table", f"unknown table {name!r}; choose one of "
                                       f"{', '.join(TABLES)}")
        buf = io.StringIO()
        for k, v in self.method().items():
            buf.write(f"# {k}: {v}\n")
        w = spreadsheet.writer(buf)  # every cell reads as data in a spreadsheet
        w.writerow(header)
        w.writerows(rows)
        return buf.getvalue()

    def figure(self, name: str, baseline: str | None = None) -> RenderedFigure:
        """`muscle_envelopes` (every lift) or `muscle_reduction` (mean envelope, every
        lift, against `baseline`: no exoskeleton if planned, else the first)."""
        # Matplotlib only when a figure is drawn: importing it costs every server start.
        from controller.evaluation.muscle_figures import envelope_cycle_figure, reduction_figure
        from controller.evaluation.rendering import render_figure

        if name == "muscle_envelopes":
            cyc = self.cycles()
            ordered = {c: cyc[c] for c in self.conditions() if c in cyc}
            return render_figure(envelope_cycle_figure(ordered, self.channels,
                                                       self.unit("mean")))
        if name == "muscle_reduction":
            bases = self.baselines()
            base = baseline or (NO_EXOSKELETON if NO_EXOSKELETON in bases else
                                (bases[0] if bases else NO_EXOSKELETON))
            # The one family drawn, not all nine (each is computed on its own).
            reds = self._reductions(("all",), ("mean",))[0]
            return render_figure(reduction_figure(reds, self.channels, base))
        raise results.ResultsError("figure", f"unknown figure {name!r}; choose one of "
                                   f"{', '.join(FIGURES)}")

    def markdown(self) -> str:
        """The reduction table in words: per baseline, channel and condition, the mean
        reduction of the mean envelope over all lifts with its interval."""
        reds = [r for r in self.reductions() if r["group"] == "all" and r["metric"] == "mean"]
        if not reds:
            return ("No muscle-activity reduction: no baseline condition with EMG in this "
                    "study.\n")
        conds = [c for c in self.conditions() if c not in self.baselines()] + \
            self.baselines()
        lines: list[str] = []
        for baseline in self.baselines():
            mine = {(r["channel"], r["condition"]): r for r in reds if r["baseline"] == baseline}
            cols = [c for c in conds if any(k[1] == c for k in mine)]
            lines += [f"**Reduction of the mean envelope against "
                      f"{registry.label(baseline)}** (%, 95 % CI; Holm-corrected p)", "",
                      "| muscle | " + " | ".join(registry.label(c) for c in cols) + " |",
                      "|" + " --- |" * (len(cols) + 1)]
            for ch in self.channels:
                cells = []
                for c in cols:
                    r = mine.get((ch, c))
                    cells.append("" if r is None or r["mean_pct"] is None else
                                 f"{r['mean_pct']:.1f} [{_fmt(r['ci_low'])}, "
                                 f"{_fmt(r['ci_high'])}] p={_fmt(r['p_holm'], 3)}")
                lines.append(f"| {ch} | " + " | ".join(cells) + " |")
            lines.append("")
        lines.append(f"Normalisation: {self.processing.get('normalisation')}; processing: "
                     + ", ".join(f"{k}={v}" for k, v in self.processing.items()) + ".")
        return "\n".join(lines) + "\n"


TABLES = ("lifts", "summary", "reductions", "repeated_measures")
FIGURES = ("muscle_envelopes", "muscle_reduction")


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else round(float(x), 6)


def _cell(v: Any) -> Any:
    return "" if v is None else v


def _fmt(x: float | None, digits: int = 1) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"


# ---------------------------------------------------------------------- reading


def study_processing(db: Session, study_id: int) -> tuple[EmgProcessing, int]:
    """The study's saved chain (defaults until set) and its mains frequency."""
    row = db.get(EmgAnalysisSettings, study_id)
    if row is None or not row.processing:
        return EmgProcessing(), row.mains_hz if row is not None else 50
    try:
        return EmgProcessing.from_dict(row.processing), row.mains_hz
    except EmgSettingsError as exc:
        raise results.ResultsError("emg_settings", str(exc)) from exc


def _trial_start(db: Session, trial_id: int) -> Marker | None:
    return db.scalars(select(Marker).where(
        Marker.trial_id == trial_id, Marker.label == "trial_start",
        Marker.source == "system").order_by(Marker.id).limit(1)).first()


def tick_times(cols: TickData, start_lsl: float) -> NDArray[np.float64]:
    """Each tick's instant on the session clock: the start marker's plus the host time
    since the first tick (device time where the host time is missing)."""
    t = cols.float_("t") if "t" in cols else np.zeros(len(cols))
    host = cols.float_("t_host") if "t_host" in cols else np.full(len(cols), np.nan)
    if host.size and np.isfinite(host).all():
        return start_lsl + (host - host[0])
    return start_lsl + (t - t[0])


def _marker_lifts(db: Session, trial_id: int) -> list[tuple[int, str, float, float]]:
    """Lifts from `lift_start` / `lift_stop` console markers (note: the kind)."""
    out: list[tuple[int, str, float, float]] = []
    open_: tuple[str, float] | None = None
    for m in db.scalars(select(Marker).where(
            Marker.trial_id == trial_id, Marker.label.in_((LIFT_START, LIFT_STOP)),
            Marker.lsl_time.is_not(None)).order_by(Marker.lsl_time, Marker.id)):
        assert m.lsl_time is not None
        if m.label == LIFT_START:
            kind = (m.note or "").strip().lower().replace("-", "_").replace(" ", "_")
            open_ = (kind if kind in LIFT_KINDS else "squat", m.lsl_time)
        elif open_ is not None and m.lsl_time > open_[1]:
            out.append((len(out), open_[0], open_[1], m.lsl_time))
            open_ = None
    return out


@dataclass
class _Envelope:
    """A processed stretch of one recording."""

    recording: EmgRecording
    t: NDArray[np.float64]  # session clock
    env: NDArray[np.float64]
    filled: bool


def _envelope(folder: Path, rec: EmgRecording, t0: float, t1: float,
              proc: EmgProcessing) -> _Envelope | None:
    """The recording's envelope (volts) over [t0, t1] on the session clock, or None if
    it holds too few samples there."""
    path = folder / f"{rec.id}.emgc"
    if not path.is_file():
        return None
    try:  # damage after the window costs nothing; in or before it, what came first
        ts, x = store.read_window(path, t0 - rec.time_offset_s, t1 - rec.time_offset_s,
                                  upto_damage=True)
    except store.EmgStoreError:  # not even the file's header reads back
        return None
    return _process(rec, ts + rec.time_offset_s, x, proc)


def _channel_flags(rec: EmgRecording) -> dict[str, list[str]]:
    chans = (rec.quality or {}).get("channels") or {}
    return {str(label): sorted(per) for label, per in chans.items() if per}


#: Flags of a recording's timestamps, which are measured again over each trial's lifts
#: (a gap elsewhere in the recording says nothing about this trial).
TIMING_FLAGS = frozenset({quality.DROPPED_SAMPLES, quality.RATE_MISMATCH,
                          quality.TIMESTAMPS_BACKWARDS})


def _recording_flags(rec: EmgRecording) -> list[str]:
    """The recording's flags that concern every trial in it: not the channels' (kept per
    channel) and not the timing's (measured per trial)."""
    chan = {f for per in ((rec.quality or {}).get("channels") or {}).values() for f in per}
    return [f for f in (rec.quality or {}).get("flags", [])
            if f not in chan and f not in TIMING_FLAGS and f != STOPPED_MID_TRIAL]


def _timing_flags(e: _Envelope, t0: float, t1: float) -> list[str]:
    """Timing flags of the envelope's samples between t0 and t1 (session clock)."""
    keep = (e.t >= t0) & (e.t <= t1)
    if keep.sum() < 2:
        return []
    flags = list(quality.timing_quality(e.t[keep], e.recording.fs).flags)
    if quality.RATE_MISMATCH in flags and quality.DROPPED_SAMPLES in flags:
        # Stamps off the nominal rate (a sped-up simulation's, or a wrong rate): a long
        # interval is no evidence of a lost sample; each lift counts its samples against
        # its duration instead (`samples_missing`).
        flags.remove(quality.DROPPED_SAMPLES)
    return flags


def _measure(lift_t: tuple[float, float], envs: Sequence[_Envelope], proc: EmgProcessing,
             mid_t: float, duration_s: float, flags: list[str]
             ) -> tuple[_Envelope | None, LiftOutcome | None, tuple[float, ...]]:
    """The lift's outcome in the first envelope covering all of it; `duration_s` (the
    lift's length in device time) says how many samples its window should hold."""
    a, b = lift_t
    for e in envs:
        if e.t[0] > a or e.t[-1] < b:
            continue
        i0 = int(np.searchsorted(e.t, a, side="left"))
        i1 = int(np.searchsorted(e.t, b, side="right"))
        im = int(np.clip(np.searchsorted(e.t, mid_t), i0 + 1, i1 - 1))
        expected = duration_s * e.recording.fs
        if i1 - i0 < max(4.0, MEASURED_SHARE * expected):
            flags.append(NO_EMG)
            return e, None, ()
        if i1 - i0 < COMPLETE_SHARE * expected:
            flags.append(f"{SAMPLES_MISSING}:{1 - (i1 - i0) / expected:.0%}")
        phases = {"lowering": (i0, im), "lifting": (im, i1)}
        out = lift_outcome(e.env, e.recording.fs, (i0, i1), phases)
        width_s = min(proc.mvc_window_s, (i1 - i0) / e.recording.fs)
        avg = moving_average_max(e.env, e.recording.fs, [(i0, i1)], width_s)
        return e, out, tuple(float(v) for v in avg)
    return None, None, ()


def _session_recordings(db: Session, session_id: int) -> list[EmgRecording]:
    """The session's recordings an analysis reads (`ANALYSED_STATUSES`): an interrupted
    one holds the trials before the crash, and carries its flag into theirs."""
    return list(db.scalars(select(EmgRecording).where(
        EmgRecording.session_id == session_id,
        EmgRecording.status.in_(ANALYSED_STATUSES)).order_by(EmgRecording.id)))


def _flag_stopped_inside(db: Session, trial: Trial, recs: Sequence[EmgRecording],
                         out: TrialEmg) -> None:
    """`stopped_mid_trial` when a recording ended inside this trial, decided now from the
    trial's span: a live stream lost before the trial's stop was known is caught too
    (the recording's own flag, set when it finished, could not know the stop)."""
    span = next((s for s in recordings.trial_spans(db, trial.session_id)
                 if s["trial_id"] == trial.id), None)
    if span is not None and any(recordings.stopped_inside(r.t_start, r.t_end, span)
                                for r in recs) and STOPPED_MID_TRIAL not in out.flags:
        out.flags.append(STOPPED_MID_TRIAL)


@dataclass
class _Prepared:
    """A trial's lifts on the session clock, waiting for the recordings' envelopes."""

    out: TrialEmg
    # index, kind, t0, t1, mid (session clock), duration (device time)
    lifts: list[tuple[int, str, float, float, float, float]]
    span: tuple[float, float] | None
    covered: bool = False
    decided: dict[int, LiftEmg] = field(default_factory=dict)


def _prepare(engine: Engine, db: Session, trial: Trial, participant: str,
             recs: Sequence[EmgRecording]) -> _Prepared:
    """The trial's lifts (ticks' truth or segments, else lift markers) and its span."""
    condition = getattr(trial, "condition", None) or trial.controller
    out = TrialEmg(trial.id, trial.session_id, participant, condition, trial.task, "none")
    start = _trial_start(db, trial.id)
    lifts: list[tuple[int, str, float, float, float, float]] = []
    cols = results.trial_columns(engine, trial, (*results.GROUND_TRUTH_FIELDS, "t_host"))
    if start is not None and start.lsl_time is not None and len(cols):
        truth = results.ground_truth(cols, trial.task, results.trial_segments(db, trial.id))
        times = tick_times(cols, start.lsl_time)
        dt = float(np.median(np.diff(times))) if times.size > 1 else 0.01
        out.lift_source = truth.source
        for tl in truth.lifts:
            # Tick i's EMG is what arrived since tick i-1 was read.
            lifts.append((tl.index, tl.kind, float(times[tl.start]) - dt,
                          float(times[tl.end]), float(times[tl.first_half_end]),
                          (tl.end - tl.start + 1) * SAMPLE_PERIOD_S))
        if truth.source == results.NO_TRUTH:
            out.note = truth.note
    if not lifts:
        marked = _marker_lifts(db, trial.id)
        if marked:
            out.lift_source = "markers"
            out.note = ""
            lifts = [(i, k, a, b, (a + b) / 2, b - a) for i, k, a, b in marked]
    if start is None or start.lsl_time is None:
        out.note = out.note or "the trial has no start marker on the session clock"
    if not lifts:
        out.note = out.note or "no lifts: no truth, segments or lift markers"
        return _Prepared(out, lifts, None)
    _flag_stopped_inside(db, trial, recs, out)
    span = (min(x[2] for x in lifts) - PAD_S, max(x[3] for x in lifts) + PAD_S)
    covered = any(r.t_start is not None and r.t_end is not None
                  and r.t_start <= span[1] and r.t_end >= span[0] for r in recs)
    if not covered:
        out.flags.append(NO_EMG)
        out.note = (f"no EMG recording of session {trial.session_id} covers trial "
                    f"{trial.id}")
    return _Prepared(out, lifts, span, covered)


def _apply(p: _Prepared, e: _Envelope, proc: EmgProcessing) -> None:
    """Measure the trial's lifts this envelope covers (a lift is measured in the first
    recording that covers its time whole) and take the recording's flags."""
    out = p.out
    if e.recording.id not in out.recordings:
        out.recordings.append(e.recording.id)
    lifts_span = (min(x[2] for x in p.lifts), max(x[3] for x in p.lifts))
    for f in [*_recording_flags(e.recording), *_timing_flags(e, *lifts_span)]:
        if f not in out.flags:
            out.flags.append(f)
    for label, fl in _channel_flags(e.recording).items():
        out.channel_flags.setdefault(label, [])
        out.channel_flags[label] += [f for f in fl if f not in out.channel_flags[label]]
    if e.filled and NON_FINITE_FILLED not in out.flags:
        out.flags.append(NON_FINITE_FILLED)
    for pos, (index, kind, a, b, mid, duration) in enumerate(p.lifts):
        if pos in p.decided:
            continue
        flags: list[str] = []
        got, outcome, avg = _measure((a, b), [e], proc, mid, duration, flags)
        if got is not None:
            p.decided[pos] = LiftEmg(index, kind, a, b, e.recording.id, outcome, avg, flags)


def _finish(p: _Prepared) -> TrialEmg:
    """The trial with every lift: measured, or listed with `no_emg`."""
    out = p.out
    for pos, (index, kind, a, b, _mid, _duration) in enumerate(p.lifts):
        lf = p.decided.get(pos) or LiftEmg(index, kind, a, b, None, None)
        if lf.outcome is None and NO_EMG not in lf.flags:
            lf.flags.append(NO_EMG)
        out.lifts.append(lf)
    missing = sum(1 for lf in out.lifts if lf.outcome is None)
    if missing and p.covered and FILE_DAMAGED not in out.flags:
        out.note = (f"{missing} of {len(out.lifts)} lifts have no EMG: no recording "
                    "covers them whole, or the stream lost most of their samples (a "
                    "stream that stopped, restarted or fell behind)")
    return out


@dataclass
class _Damage:
    """Where a recording's file stopped reading back (session clock), and why."""

    after: float
    why: str


def _one_pass(folder: Path, rec: EmgRecording, spans: Sequence[tuple[float, float]],
              proc: EmgProcessing, damage: list[_Damage] | None = None
              ) -> Iterable[tuple[int, _Envelope]]:
    """(span index, envelope) of each span the recording holds, from one pass over its
    chunks: a span is processed as soon as the chunks have passed it, so only the raw
    samples of the spans still open are held (the file is read once, however many
    trials it covers). A chunk that does not read back ends the pass there: the spans
    still open get what came before it, and `damage` says where (one damaged file
    costs its own trials' later lifts, not the study's results)."""
    path = folder / f"{rec.id}.emgc"
    if not spans:
        return
    if not path.is_file():
        if damage is not None:
            damage.append(_Damage(-math.inf, "its file is missing"))
        return
    off = rec.time_offset_s
    parts: dict[int, tuple[list[NDArray[np.float64]], list[NDArray[np.float32]]]] = {
        i: ([], []) for i in range(len(spans))}

    def done(i: int) -> tuple[int, _Envelope] | None:
        ts_parts, xs_parts = parts.pop(i)
        if not ts_parts:
            return None
        e = _process(rec, np.concatenate(ts_parts) + off,
                     np.concatenate(xs_parts).astype(np.float64), proc)
        return None if e is None else (i, e)

    last = -math.inf
    why: list[str] = []
    for t, x in store.iter_chunks(path, why):
        if t.size == 0:
            continue
        ts = t + off
        finite = ts[np.isfinite(ts)]
        if finite.size:
            last = max(last, float(finite.max()))
        for i in list(parts):
            a, b = spans[i]
            if ts[-1] >= a and ts[0] < b:
                keep = (ts >= a) & (ts < b)
                if keep.any():
                    parts[i][0].append(t[keep])
                    parts[i][1].append(x[keep])
            if ts.max() >= b:
                got = done(i)
                if got is not None:
                    yield got
    if why and damage is not None:
        damage.append(_Damage(last, why[0]))
    for i in list(parts):
        got = done(i)
        if got is not None:
            yield got


def _process(rec: EmgRecording, t: NDArray[np.float64], x: NDArray[np.float64],
             proc: EmgProcessing) -> _Envelope | None:
    """The envelope (volts) of raw samples on the session clock, or None if too few."""
    if t.size < max(64, int(0.5 * rec.fs)):
        return None
    filled = False
    if not np.isfinite(x).all():
        x, _ = fill_non_finite(x)
        filled = True
    try:
        env = process(x, rec.fs, proc)
    except (ValueError, EmgSettingsError):
        return None
    return _Envelope(rec, t, env, filled)


def session_trials(engine: Engine, db: Session, folder: Path, trials: Sequence[Trial],
                   participant: str, proc: EmgProcessing,
                   recs: Sequence[EmgRecording]) -> list[TrialEmg]:
    """The session's trials' lifts measured in its stored EMG (volts), each recording
    read once."""
    prepared = [_prepare(engine, db, t, participant, recs) for t in trials]
    for rec in recs:
        if rec.t_start is None or rec.t_end is None:
            continue
        mine = [p for p in prepared if p.span is not None
                and rec.t_start <= p.span[1] and rec.t_end >= p.span[0]]
        spans = [p.span for p in mine if p.span is not None]
        damage: list[_Damage] = []
        for i, e in _one_pass(folder, rec, spans, proc, damage):
            _apply(mine[i], e, proc)
        for d in damage:
            for p in mine:
                # A trial whose last lift ends before the damage lost nothing (its 1 s pad
                # may run past it).
                last_lift = max((x[3] for x in p.lifts), default=-math.inf)
                if last_lift > d.after and FILE_DAMAGED not in p.out.flags:
                    p.out.flags.append(FILE_DAMAGED)
                    where = (f"after {d.after:.3f} s on the session clock"
                             if math.isfinite(d.after) else "from its start")
                    p.out.note = (f"EMG recording {rec.id} does not read back {where} "
                                  f"({d.why}); later lifts have no EMG")
    return [_finish(p) for p in prepared]


def trial_emg(engine: Engine, db: Session, folder: Path, trial: Trial, participant: str,
              proc: EmgProcessing, recs: Sequence[EmgRecording]) -> TrialEmg:
    """One trial's lifts measured in the session's stored EMG (volts)."""
    return session_trials(engine, db, folder, [trial], participant, proc, recs)[0]


def _mvc_reference(db: Session, folder: Path, recs: Sequence[EmgRecording],
                   proc: EmgProcessing, channels: Sequence[str],
                   montage: Sequence[dict[str, Any]]) -> tuple[float, ...] | None:
    """The session's MVC reference per channel (volts), None if a channel has none."""
    best = dict.fromkeys(channels, -math.inf)
    for rec in recs:
        wins = mvc.windows(db, rec)
        for c, m in enumerate(montage):
            for a, b in wins.get((str(m.get("muscle")), str(m.get("side"))), []):
                e = _envelope(folder, rec, a + rec.time_offset_s - PAD_S,
                              b + rec.time_offset_s + PAD_S, proc)
                if e is None:
                    continue
                i0, i1 = (int(np.searchsorted(e.t, a + rec.time_offset_s)),
                          int(np.searchsorted(e.t, b + rec.time_offset_s)))
                if i1 - i0 < max(1, round(proc.mvc_window_s * rec.fs)):
                    continue
                ref = mvc_reference(e.env[:, [c]], rec.fs, [(i0, i1)], proc.mvc_window_s)
                best[channels[c]] = max(best[channels[c]], float(ref[0]))
    values = tuple(best[ch] for ch in channels)
    return values if all(math.isfinite(v) and v > 0 for v in values) else None


def _normalise(trials: Sequence[TrialEmg], ref: SessionReference) -> None:
    """Divide every lift's outcome of the session by the reference (in place)."""
    scale = np.asarray(ref.values, dtype=np.float64)
    for t in trials:
        for lf in t.lifts:
            o = lf.outcome
            if o is None:
                continue
            lf.outcome = LiftOutcome(_scaled(o.lift, scale),
                                     {k: _scaled(v, scale) for k, v in o.phases.items()},
                                     o.cycle / scale)


def _scaled(w: Any, scale: NDArray[np.float64]) -> Any:
    from controller.emg.outcomes import WindowOutcome

    return WindowOutcome(tuple(float(v) for v in np.asarray(w.peak) / scale),
                         tuple(float(v) for v in np.asarray(w.mean) / scale),
                         tuple(float(v) for v in np.asarray(w.iemg) / scale), w.duration_s)


def _session_reference(db: Session, folder: Path, recs: Sequence[EmgRecording],
                       trials: Sequence[TrialEmg], proc: EmgProcessing,
                       channels: Sequence[str], montage: Sequence[dict[str, Any]]
                       ) -> SessionReference:
    lifts = [lf for t in trials for lf in t.lifts if lf.outcome is not None]
    n = len(channels)
    if proc.normalisation == VOLTS or not lifts:
        return SessionReference("none", (1.0,) * n)
    if proc.normalisation == "mvc":
        values = _mvc_reference(db, folder, recs, proc, channels, montage)
        if values is None:
            return SessionReference("none", (1.0,) * n, [NO_MVC])
        peak_avg = np.max([lf.peak_average for lf in lifts], axis=0)
        ratio = peak_avg / np.asarray(values)
        exceeds = {ch: float(r) for ch, r in zip(channels, ratio, strict=True) if r > 1.0}
        return SessionReference("mvc", values, [EXCEEDS_MVC] if exceeds else [], exceeds)
    if proc.normalisation == "task_peak":
        ref = np.max([lf.outcome.lift.peak for lf in lifts if lf.outcome], axis=0)
    else:
        w = np.asarray([lf.outcome.lift.duration_s for lf in lifts if lf.outcome])
        m = np.asarray([lf.outcome.lift.mean for lf in lifts if lf.outcome])
        ref = (m * w[:, None]).sum(axis=0) / w.sum()
    values = tuple(float(v) for v in ref)
    if not all(math.isfinite(v) and v > 0 for v in values):
        return SessionReference("none", (1.0,) * n, ["reference_not_positive"])
    return SessionReference(proc.normalisation, values)


def study_muscle_results(engine: Engine, db: Session, folder: Path, study_id: int,
                         site: str | None = None) -> MuscleResults:
    """Every completed trial's muscle activity and the study's aggregates."""
    proc, mains = study_processing(db, study_id)
    out = MuscleResults(study_id, proc.to_dict(), mains)
    participants = list(db.scalars(select(Participant).where(
        results.counted(study_id, site)).order_by(Participant.id)))
    for p in participants:
        sessions = list(db.scalars(select(StudySession).where(
            StudySession.participant_id == p.id).order_by(StudySession.id)))
        for sess in sessions:
            recs = _session_recordings(db, sess.id)
            trials = [t for t in db.scalars(select(Trial).where(
                Trial.session_id == sess.id).order_by(Trial.planned_order))
                if t.status == "completed" and t.controller != registry.idle()]
            if not trials:
                continue
            montage: list[dict[str, Any]] = []
            if recs:
                row = db.get(EmgMontage, recs[0].montage_id)
                montage = list(row.channels) if row is not None else []
                labels = list(recs[0].labels)
                if not out.channels:
                    out.channels = [_channel_name(m, lb) for m, lb in
                                    zip(montage, labels, strict=False)] or labels
            emg = session_trials(engine, db, folder, trials, p.code, proc, recs)
            if recs and out.channels:
                out.references[sess.id] = _session_reference(
                    db, folder, recs, emg, proc, out.channels, montage)
                _normalise(emg, out.references[sess.id])
                if proc.normalisation.startswith("task") and any(
                        FILE_DAMAGED in t.flags for t in emg):
                    out.notes.append(
                        f"session {sess.id}: normalised to the {proc.normalisation} of the "
                        "lifts with EMG; the lifts a damaged file lost are not in it")
            out.trials += emg
    if not out.trials or not any(lf.outcome for t in out.trials for lf in t.lifts):
        out.notes.append("no lift of this study has EMG: subscribe an EMG stream to the "
                         "sessions, or import the recordings (docs/muscle-activity.md)")
    for sid, ref in out.references.items():
        if NO_MVC in ref.flags:
            out.notes.append(f"session {sid}: the study normalises to MVC but the session "
                             "has no MVC repetition for every channel; its values are in "
                             "volts (normalisation none)")
        if ref.exceeds:
            out.notes.append(f"session {sid}: task activity exceeds the MVC on "
                             + ", ".join(f"{k} ({v:.2f} x MVC)" for k, v in ref.exceeds.items())
                             + ": the MVC was not maximal; values above 1 are kept")
    for t in out.trials:
        if t.note:
            out.notes.append(f"trial {t.trial_id}: {t.note}")
    return out


def _channel_name(m: dict[str, Any], label: str) -> str:
    muscle, side = m.get("muscle"), m.get("side")
    return f"{muscle}_{side}" if muscle and side else label


def emg_fingerprint(db: Session, study_id: int) -> tuple[Any, ...]:
    """What the muscle results read besides the trials: recordings, settings, MVC
    markers (a cache is valid while this and `results_cache.fingerprint` stay the same)."""
    sessions = select(StudySession.id).join(
        Participant, StudySession.participant_id == Participant.id).where(
        Participant.study_id == study_id)
    recs = tuple(db.execute(select(EmgRecording.id, EmgRecording.status,
                                   EmgRecording.n_samples, EmgRecording.time_offset_s)
                            .where(EmgRecording.session_id.in_(sessions))
                            .order_by(EmgRecording.id)).all())
    settings = db.get(EmgAnalysisSettings, study_id)
    marks = tuple(db.scalars(select(Marker.id).where(
        Marker.session_id.in_(sessions),
        Marker.label.in_((LIFT_START, LIFT_STOP, mvc.MVC_START, mvc.MVC_STOP)))
        .order_by(Marker.id)))
    return (recs, None if settings is None else (
        json.dumps(settings.processing, sort_keys=True), settings.mains_hz), marks)


class MuscleResultsCache:
    """The last few studies' muscle results (reading EMG takes seconds)."""

    def __init__(self, size: int = 2) -> None:
        self.size = size
        self._entries: dict[tuple[Any, ...], MuscleResults] = {}

    def get(self, engine: Engine, db: Session, folder: Path, study_id: int,
            site: str | None) -> MuscleResults:
        key = (str(engine.url), str(folder), study_id, site,
               results_cache.fingerprint(db, study_id, site), emg_fingerprint(db, study_id))
        hit = self._entries.get(key)
        if hit is None:
            hit = study_muscle_results(engine, db, folder, study_id, site)
            if len(self._entries) >= self.size:
                self._entries.pop(next(iter(self._entries)))
            self._entries[key] = hit
        return hit


#: One per process: the API's routes and the exports share it.
CACHE = MuscleResultsCache()


def iter_export(res: MuscleResults) -> Iterable[tuple[str, str]]:
    """(file name, text) of the muscle results for a study's trial-data export."""
    for name in TABLES:
        yield f"muscle_{name}.csv", res.csv(name)
    yield "muscle_method.json", json.dumps(res.method(), indent=1)


def export_files(engine: Engine, study_id: int, site: str | None) -> list[tuple[str, str]]:
    """(file name, text) of the study's muscle-activity tables from its stored EMG, with
    the method, for the owner's trial-data export; a study whose EMG cannot be read gets
    a note saying why instead (the export never fails on it)."""
    try:
        with Session(engine) as db:
            res = CACHE.get(engine, db, store.engine_emg_folder(engine), study_id, site)
            return list(iter_export(res))
    except Exception as exc:  # a note in the archive, never a failed export
        return [("README.txt", f"muscle activity not computed: {exc}\n")]
