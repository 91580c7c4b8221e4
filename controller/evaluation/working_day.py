"""A stairs-heavy working day: mostly walking and stairs, a few lifts.

The paper's protocol holds 20 lifts against one 10 m walk and one stair trial, so it
barely tests what learned priors are for: a wearer whose use is mostly gait. This
script is the opposite case. One block is

    stairs bout, walking bout, stairs bout, one lift cycle (pick a 5 kg box up, stand
    about a second, put it down),

with standing between motions; the lift cycles rotate through squat/squat, stoop
left/stoop right and stoop right/stoop left, so three blocks hold two lifts of each
kind. The bouts are the protocol's own (`controller.sim.scripts`: 11 stairs up, a
landing turn, 11 down; a 10 m walk, a turn and back). Six blocks (the default) last
about 11 minutes: 12 stair bouts, 6 walking bouts, 12 lifts.

Confirmed motions (what a count-based prior learns from): each lift, as its kind, and
each gait bout (a maximal run of walking, turning or stairs between standing periods)
as one "other" motion, both from the simulation's ground truth, as markers or an
experimenter's log would confirm them in a study. The lift segmentation does not
propose gait segments, so it cannot be the unit for "other".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller.evaluation.columns import TickData
from controller.evaluation.lifts import GaitTrial, lifts_from_truth, trials_from_truth
from controller.evaluation.metrics import DecisionOutcome, count_false_positives
from controller.evaluation.study import evaluate_recording
from controller.runner.replay import AngleRecording
from controller.sim.activity_kinds import ACTIVITIES, GAIT_KINDS
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import LiftStep, Script, Stand, Step, get_script, realise
from controller.tick_record import MODEL_NAMES

DEFAULT_BLOCKS = 6
BOX_KG = 5.0
_CYCLES: tuple[tuple[str, str], ...] = (("squat", "squat"), ("stoop_left", "stoop_right"),
                                        ("stoop_right", "stoop_left"))
#: Metrics of one working day, per participant and condition.
DAY_METRICS: tuple[str, ...] = ("fp_stairs", "fp_walking", "stairs_h", "walking_h",
                                "lifts", "correct", "wrong", "missed")


def working_day_script(blocks: int = DEFAULT_BLOCKS) -> Script:
    """The stairs-heavy working day of `blocks` blocks (see the module docstring)."""
    if not 1 <= blocks <= 100:
        raise ValueError(f"blocks: must be within 1..100, got {blocks}")
    stairs, walk = get_script("stairs").steps, get_script("walking").steps
    steps: list[Step] = []
    for b in range(blocks):
        pick, put = _CYCLES[b % len(_CYCLES)]
        steps += [*stairs, *walk, *stairs, Stand((2.0, 4.0)), LiftStep(pick, True),
                  Stand((0.8, 1.3), holding_box=True), LiftStep(put, False),
                  Stand((2.0, 4.0))]
    return Script(f"stairs-working-day-{blocks}", tuple(steps), BOX_KG)


def day_recording(p: VirtualParticipant, seed: int, blocks: int,
                  repetition: int) -> AngleRecording:
    """What the encoders see during one working day (offsets and drift included), with
    the ground truth; `repetition` makes another day of the same wearer."""
    traj = realise(working_day_script(blocks), p, seed, repetition)
    q = traj.theta + p.encoder_offset(traj.t)
    return AngleRecording(traj.t, q, traj.activity_names().tolist(),
                          traj.lift.astype(np.int64))


def confirmed_motions(activity: list[str] | tuple[str, ...]) -> list[str]:
    """The day's motions in order: each lift as its kind, each gait bout as "other"
    (runs of one activity code; standing separates motions)."""
    gait = set(GAIT_KINDS)
    out: list[str] = []
    prev = ""
    for a in activity:
        if a != prev:
            if a in MODEL_NAMES:
                out.append(a)
            elif a in gait and prev not in gait:
                out.append("other")
        prev = a
    unknown = set(activity) - set(ACTIVITIES)
    if unknown:
        raise ValueError(f"unknown activities {sorted(unknown)}")
    return out


@dataclass(frozen=True)
class DayOutcome:
    """One controller run through one working day."""

    metrics: dict[str, float]
    trials: tuple[GaitTrial, ...]


def day_metrics(columns: TickData, participant: str, controller: str) -> DayOutcome:
    """False positive lock signals (the paper's count: rising edges of the held
    command) in stair-walking and walking bouts, their hours, and the lift decisions."""
    trials = trials_from_truth(columns)
    ev = evaluate_recording(columns, participant, controller, lifts_from_truth(columns),
                            trials)
    fps = count_false_positives(columns, trials)

    def total(kind: str, attr: str) -> float:
        return float(sum(getattr(f, attr) for f in fps if f.trial.kind == kind))

    lifts = list(ev.lifts)
    return DayOutcome({
        "fp_stairs": total("stair_walking", "signals"),
        "fp_walking": total("walking", "signals"),
        "stairs_h": total("stair_walking", "duration_s") / 3600.0,
        "walking_h": total("walking", "duration_s") / 3600.0,
        "lifts": float(len(lifts)),
        "correct": float(sum(o.decision == DecisionOutcome.CORRECT for o in lifts)),
        "wrong": float(sum(o.decision == DecisionOutcome.WRONG for o in lifts)),
        "missed": float(sum(o.decision == DecisionOutcome.MISSED for o in lifts)),
    }, tuple(trials))
