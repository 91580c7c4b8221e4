"""Muscle activity of virtual participants: activation truth, simulated sEMG, per-lift outcomes.

Why: the study's main physiological outcome is how much each controller lowers back and
hip extensor activity against a baseline. A virtual cohort can report it *and* check the
whole EMG chain against the activation that generated the signal.

Per virtual participant (one simulated session; `SessionEmg`):

1. **Electrodes and MVC.** One 12-channel sEMG generator for the whole session
   (`controller.sim.surface_emg`, seeded by the participant: the electrode gains stay
   the same across conditions, the noise does not repeat). A simulated MVC trial comes
   first: every muscle ramps to full activation in 1 s, holds it for 3 s and relaxes in
   1 s (all channels in one trial: the generator's channels are independent, so this is
   the same as one trial per muscle). Assumption: the participant reaches full
   activation in the MVC (real MVCs are often submaximal; that scales every normalised
   value up but leaves reductions, which are ratios, unchanged). The reference is the
   largest 0.5 s moving average of the processed envelope in the hold
   (`controller.emg.normalisation.mvc_reference`).
2. **Each condition's lift trial.** Activation truth from `MuscleModel` with the
   simulation's hip moments per leg minus the exoskeleton's torque per side (the
   replay's `torque_left/right`); zero torque for a condition whose registration says
   the exoskeleton is not worn, and for the baselines, which never lock: unlocked, the
   cam link follows the output link and the spring gives no torque
   (`controller.sim.plant`; a test checks it on a replay), so the simulation skips
   their replay. Consequence, stated: the simulation does not model the device's mass
   or straps, so `springs_free` and `no_exoskeleton` differ only by their repetition's
   movement draws.
3. **Only the lifts are sampled.** sEMG at 2 kHz is generated for each lift (existing
   segmentation, `lifts_from_truth`) with 0.5 s either side, overlapping spans
   merged and put back to back as one continuous recording (the zero-phase filters'
   edges fall on standing, not on a lift); walking and stairs are not generated
   (muscle activity is an outcome of lifts). A motion artefact starts at every lift
   onset.
4. **Processing** by `controller.emg.processing.process` with the project's defaults
   plus a 50 Hz notch (the generator puts 50 Hz mains hum on every channel), float32
   filters, then division by the MVC reference (fraction of MVC).
5. **Outcomes** per lift (`controller.emg.outcomes.lift_outcome`): peak, mean and
   integrated envelope per muscle and side, and the envelope over the normalised lift
   cycle; the same outcomes of the activation truth (at the tick rate) beside them.
   Kept per participant and condition: the mean over lifts, for all lifts and per task
   (squat, stoop), and the mean cycle.

The truth check (`tests/controller/evaluation/test_muscle_activity.py`): the reduction
recovered from sEMG equals the reduction of the activation truth, per participant of
ten lifts and every channel, within 3 percentage points for the mean and iEMG and 8 for
the peak (which picks the envelope's largest upward excursion). Over a 20-participant
cohort the means agree within 0.5 points.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.controllers import registry
from controller.emg.normalisation import mvc_reference
from controller.emg.outcomes import CYCLE_POINTS, lift_outcome, window_outcome
from controller.emg.processing import EmgProcessing, process
from controller.evaluation.columns import TickData
from controller.evaluation.lifts import Lift, lifts_from_truth
from controller.runner.replay import AngleRecording
from controller.sim.muscles import CHANNELS, MuscleModel, channel_label
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import get_script, realise
from controller.sim.surface_emg import FS_HZ, SurfaceEmgGenerator

FloatArray = NDArray[np.float64]

TICK_HZ = 100.0
UPSAMPLE = int(FS_HZ / TICK_HZ)
#: Channel labels, `<muscle>_<side>`, in `CHANNELS` order.
LABELS: tuple[str, ...] = tuple(channel_label(m, s) for m, s in CHANNELS)
OUTCOMES: tuple[str, ...] = ("peak", "mean", "iemg")
OUTCOME_UNITS: dict[str, str] = {"peak": "fraction of MVC", "mean": "fraction of MVC",
                                 "iemg": "fraction of MVC x s"}
#: Tasks the outcomes are kept for: every lift, squats, stoops (either side).
TASKS: tuple[str, ...] = ("all", "squat", "stoop")
LIFT_PAD_S = 0.5
MVC_RAMP_S = 1.0
MVC_HOLD_S = 3.0
MVC_ACTIVATION = 1.0
#: The chain of `controller.emg` with a 50 Hz notch (the simulated mains).
PROCESSING = EmgProcessing(notch_hz=50)


def _task(lift: Lift) -> str:
    return "squat" if lift.kind == "squat" else "stoop"


def lift_trial(p: VirtualParticipant, seed: int, script: str,
               repetition: int) -> tuple[AngleRecording, FloatArray]:
    """What `cohort.trial_recording` returns, plus the wearer's own hip extension
    moments (K, 2) Nm of the same realisation (one realisation, not two)."""
    traj = realise(get_script(script), p, seed, repetition)
    q = traj.theta + p.encoder_offset(traj.t)
    rec = AngleRecording(traj.t, q, traj.activity_names().tolist(), traj.lift.astype(np.int64))
    return rec, np.asarray(traj.torque, dtype=np.float64)


def recording_lifts(rec: AngleRecording) -> list[Lift]:
    """The lifts of a recording's ground truth, by the cohort's segmentation."""
    if rec.activity is None or rec.lift_index is None:
        raise ValueError("the recording carries no ground truth to find its lifts")
    return lifts_from_truth(TickData({"truth_lift": rec.lift_index,
                                      "truth_activity": np.asarray(rec.activity)}))


def lift_spans(lifts: Sequence[Lift], n_ticks: int, pad: int) -> list[tuple[int, int]]:
    """Tick spans `(start, stop)` (stop excluded) covering every lift with `pad` ticks
    either side, clipped to the recording, overlapping spans merged."""
    spans: list[tuple[int, int]] = []
    for lf in sorted(lifts, key=lambda x: x.start):
        a, b = max(0, lf.start - pad), min(n_ticks, lf.end + 1 + pad)
        if spans and a <= spans[-1][1]:
            spans[-1] = (spans[-1][0], max(spans[-1][1], b))
        else:
            spans.append((a, b))
    return spans


@dataclass(frozen=True)
class ConditionMuscles:
    """One participant's lift trial in one condition: means over its lifts.

    `emg[task][outcome][channel]` from the processed sEMG (fraction of MVC),
    `truth[task][outcome][channel]` the same outcome of the generating activation
    (fraction of maximum), `cycle[channel]` the mean sEMG envelope over the normalised
    lift cycle (CYCLE_POINTS values, all lifts), `peak_torque_nm` the mean over lifts of
    the exoskeleton's peak torque (mean of both sides).
    """

    condition: str
    n_lifts: int
    emg: dict[str, dict[str, dict[str, float]]]
    truth: dict[str, dict[str, dict[str, float]]]
    cycle: dict[str, list[float]] = field(default_factory=dict)
    peak_torque_nm: float = math.nan

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ConditionMuscles:
        """Inverse of `dataclasses.asdict` (None back to NaN)."""
        def num(x: Any) -> float:
            return math.nan if x is None else float(x)

        def nest(t: Mapping[str, Any]) -> dict[str, dict[str, dict[str, float]]]:
            return {k: {o: {c: num(v) for c, v in ch.items()} for o, ch in out.items()}
                    for k, out in t.items()}

        return cls(str(d["condition"]), int(d["n_lifts"]), nest(d["emg"]), nest(d["truth"]),
                   {c: [num(v) for v in vs] for c, vs in d.get("cycle", {}).items()},
                   num(d.get("peak_torque_nm")))


@dataclass(frozen=True)
class ParticipantMuscles:
    """One participant's session: the MVC reference per channel (V) and each condition."""

    mvc_v: dict[str, float]
    conditions: dict[str, ConditionMuscles]
    #: EMG generated and processed (False: activation truth only, as in the sweep).
    emg: bool = True

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ParticipantMuscles:
        """Inverse of `dataclasses.asdict`."""
        return cls({k: float(v) for k, v in d["mvc_v"].items()},
                   {k: ConditionMuscles.from_dict(v) for k, v in d["conditions"].items()},
                   bool(d.get("emg", True)))


def _means(per_lift: list[tuple[str, dict[str, tuple[float, ...]]]]
           ) -> dict[str, dict[str, dict[str, float]]]:
    """Per task and outcome, the mean over lifts of each channel."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for task in TASKS:
        rows = [o for t, o in per_lift if task in ("all", t)]
        out[task] = {}
        for name in OUTCOMES:
            if rows:
                m = np.mean(np.array([r[name] for r in rows], dtype=np.float64), axis=0)
                out[task][name] = {lab: float(v) for lab, v in zip(LABELS, m, strict=True)}
            else:
                out[task][name] = {lab: math.nan for lab in LABELS}
    return out


def _outcome_tuple(w: Any) -> dict[str, tuple[float, ...]]:
    return {"peak": w.peak, "mean": w.mean, "iemg": w.iemg}


class SessionEmg:
    """One participant's simulated EMG session: electrodes, MVC, then conditions."""

    def __init__(self, p: VirtualParticipant, emg: bool = True,
                 processing: EmgProcessing = PROCESSING) -> None:
        self.participant = p
        self.model = MuscleModel.for_participant(p)
        self.emg = emg
        self.processing = processing
        self.generator = SurfaceEmgGenerator(len(CHANNELS), p.seed, upsample=UPSAMPLE)
        self.mvc_v = self._mvc() if emg else np.ones(len(CHANNELS))
        self.conditions: dict[str, ConditionMuscles] = {}

    def _mvc(self) -> FloatArray:
        ramp, hold = int(MVC_RAMP_S * FS_HZ), int(MVC_HOLD_S * FS_HZ)
        level = np.concatenate([np.linspace(0.0, MVC_ACTIVATION, ramp),
                                np.full(hold, MVC_ACTIVATION),
                                np.linspace(MVC_ACTIVATION, 0.0, ramp)])
        self.generator.onset()
        block = self.generator.push_samples(np.repeat(level[:, None], len(CHANNELS), axis=1))
        env = process(block.samples, FS_HZ, self.processing)
        return mvc_reference(env, FS_HZ, [(ramp, ramp + hold)], self.processing.mvc_window_s)

    def result(self) -> ParticipantMuscles:
        """What the session measured so far."""
        return ParticipantMuscles({lab: float(v) for lab, v in zip(LABELS, self.mvc_v,
                                                                   strict=True)},
                                  dict(self.conditions), self.emg)

    def condition(self, name: str, lifts: Sequence[Lift], human_nm: FloatArray,
                  exo_nm: FloatArray | None) -> ConditionMuscles:
        """One condition's lift trial. `exo_nm` (K, 2) the exoskeleton's torque per side;
        None or a condition whose exoskeleton is not worn: zero."""
        human = np.asarray(human_nm, dtype=np.float64)
        if exo_nm is None or not registry.exoskeleton_worn(name):
            exo = np.zeros_like(human)
        else:
            exo = np.nan_to_num(np.asarray(exo_nm, dtype=np.float64), nan=0.0)
        act = self.model.activation(human, exo)
        truth_lifts = []
        emg_lifts: list[tuple[str, dict[str, tuple[float, ...]]]] = []
        cycles: list[FloatArray] = []
        torques = []
        for lf in lifts:
            w = window_outcome(act, TICK_HZ, (lf.start, lf.end + 1))
            truth_lifts.append((_task(lf), _outcome_tuple(w)))
            torques.append(float(np.mean(exo[lf.start:lf.end + 1].max(axis=0))))
        if self.emg:
            # The spans back to back: the generator's clock and filter state run on
            # across them, so this is one continuous recording of the lifts alone
            # (standing either side of every cut), processed in one call.
            spans = lift_spans(lifts, act.shape[0], int(LIFT_PAD_S * TICK_HZ))
            at = np.cumsum([0] + [b - a for a, b in spans])
            where = {}
            for (a, b), off in zip(spans, at[:-1], strict=True):
                for lf in lifts:
                    if a <= lf.start and lf.end < b:
                        where[lf.index] = int(off) + lf.start - a
            env = self._envelope(np.concatenate([act[a:b] for a, b in spans]),
                                 sorted(where.values()))
            for lf in lifts:
                s0 = where[lf.index]
                o = lift_outcome(env, FS_HZ, (s0 * UPSAMPLE,
                                              (s0 + lf.end + 1 - lf.start) * UPSAMPLE))
                emg_lifts.append((_task(lf), _outcome_tuple(o.lift)))
                cycles.append(o.cycle)
        cycle = (np.mean(np.stack(cycles), axis=0) if cycles
                 else np.full((CYCLE_POINTS, len(LABELS)), math.nan))
        out = ConditionMuscles(
            name, len(lifts), _means(emg_lifts) if self.emg else {}, _means(truth_lifts),
            {lab: [round(float(v), 5) for v in cycle[:, i]] for i, lab in enumerate(LABELS)}
            if self.emg else {},
            float(np.mean(torques)) if torques else math.nan)
        self.conditions[name] = out
        return out

    def _envelope(self, act: FloatArray, onsets: Sequence[int]) -> FloatArray:
        """sEMG for tick-rate activation `act`, processed and normalised to the MVC;
        a motion artefact at each onset (tick index into `act`)."""
        cuts = sorted({0, act.shape[0], *(int(o) for o in onsets if 0 <= o < act.shape[0])})
        parts = []
        for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
            if lo in onsets:
                self.generator.onset()
            parts.append(self.generator.push(act[lo:hi]).samples)
        raw = np.concatenate(parts, axis=0)
        return process(raw, FS_HZ, self.processing) / self.mvc_v


def record_condition(session: SessionEmg, name: str, columns: TickData,
                     human_nm: FloatArray) -> ConditionMuscles:
    """A replayed controller's lift trial: its lifts (`lifts_from_truth`) and the
    exoskeleton's torque per side from the replay's columns."""
    cols = TickData.of(columns)
    exo = np.column_stack([cols.float_("torque_left"), cols.float_("torque_right")])
    return session.condition(name, lifts_from_truth(cols), human_nm, exo)


def record_baselines(session: SessionEmg, seed: int, script: str,
                     first_repetition: int) -> list[ConditionMuscles]:
    """The baseline conditions, each its own repetition of the script after the
    controllers' (new movement draws, as a new trial): never locked, so no exoskeleton
    torque (module docstring) and no replay."""
    out = []
    for k, name in enumerate(registry.baselines()):
        rec, human_nm = lift_trial(session.participant, seed, script, first_repetition + k)
        out.append(session.condition(name, recording_lifts(rec), human_nm, None))
    return out
