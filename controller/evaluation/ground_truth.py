"""A trial's ground truth from its ticks: which lifts and gait trials it holds, and where
that knowledge came from. Pure (tick columns in, lifts out): the study's results, the
virtual study, the replication and the what-if replay all decide it here, one way.

Ground truth, in order of preference:

1. the simulation's truth columns (`truth_lift`, `truth_activity`) when the ticks carry
   them (a simulated wearer);
2. the experimenter's lift segments of the trial (start, end, label), the ground truth
   of a trial on hardware; a segment still "unlabelled" makes the trial wait
   (`truth: "none"`, the note says why) rather than count fewer lifts;
3. for a walking or stair-walking task, the whole trial as one gait trial (the paper
   recorded those trials on their own);
4. otherwise the lifts are unknown: the result says so (`truth: "none"`) instead of
   reporting zeros.

A trial starts and stops at arbitrary moments of the wearer's motion, so a lift that
was already under way at the first tick or still under way at the last one is
incomplete: it is left out (`incomplete_lifts` counts them), since its first half, the
window the paper's metrics look at, is not the lift's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from controller.evaluation.columns import TickData
from controller.evaluation.lifts import (
    GaitTrial,
    Lift,
    lifts_from_segments,
    lifts_from_truth,
    trials_from_truth,
    whole_recording_trial,
)

TruthSource = Literal["simulation", "segments", "task", "none"]
#: The truth source of a trial whose lifts are unknown.
NO_TRUTH: TruthSource = "none"
#: Tasks whose whole trial is a gait trial when the ticks carry no truth.
GAIT_TASKS: dict[str, str] = {"walking": "walking", "stairs": "stair_walking",
                              "stair_walking": "stair_walking"}


@dataclass(frozen=True)
class TrialTruth:
    """Lifts and gait trials of one trial's ticks, and where they came from."""

    source: TruthSource
    lifts: tuple[Lift, ...] = ()
    gait: tuple[GaitTrial, ...] = ()
    incomplete_lifts: int = 0
    note: str = ""


def has_truth(cols: TickData) -> bool:
    """Whether the ticks carry the simulation's truth (a simulated wearer)."""
    if "truth_activity" not in cols or len(cols) == 0:
        return False
    return bool((cols.str_("truth_activity") != "").any())


def renumbered(cols: TickData) -> TickData:
    """The columns with every contiguous run of one `truth_lift` value numbered anew.

    The simulated device loops its script, and each repetition numbers its lifts from
    0 again; a trial that spans the loop therefore holds lift 3 twice. Each run of ticks
    is one lift, whatever its number.
    """
    lift = cols.int_("truth_lift")
    new = np.full(lift.shape, -1, dtype=np.int64)
    k = 0
    start = 0
    n = lift.size
    while start < n:
        end = start
        while end + 1 < n and lift[end + 1] == lift[start]:
            end += 1
        if lift[start] >= 0:
            new[start:end + 1] = k
            k += 1
        start = end + 1
    return cols.with_columns({"truth_lift": new})


def ground_truth(cols: TickData, task: str,
                 segments: Sequence[tuple[int, int, str]] = ()) -> TrialTruth:
    """The lifts and gait trials of a trial's ticks (see the module docstring);
    `segments` are the experimenter's (start, end, label) of the trial."""
    n = len(cols)
    if n == 0:
        return TrialTruth("none", note="the trial has no stored ticks")
    if has_truth(cols):
        every = lifts_from_truth(renumbered(cols))
        complete = tuple(lf for lf in every if lf.start > 0 and lf.end < n - 1)
        gait = tuple(trials_from_truth(cols))
        return TrialTruth("simulation", complete, gait, len(every) - len(complete),
                          "lifts and gait trials from the simulation's truth columns")
    kind = GAIT_TASKS.get(task.strip().lower().replace("-", "_"))
    gait_trials = (whole_recording_trial(n, kind),) if kind is not None else ()
    if segments:
        try:
            lifts = tuple(lifts_from_segments(segments, n_ticks=n))
        except ValueError as exc:
            return TrialTruth("none", note=f"the experimenter's segments cannot be used "
                              f"yet: {exc}")
        return TrialTruth("segments", lifts, gait_trials,
                          note=f"{len(lifts)} lifts from the experimenter's segments")
    if kind is not None:
        return TrialTruth("task", (), gait_trials,
                          note=f"the whole trial is one {kind} trial (task {task!r})")
    return TrialTruth("none", note="lifts unknown: no truth columns and no experimenter "
                      "segments (POST /api/trials/{id}/segment proposes them)")
