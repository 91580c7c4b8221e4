"""A long-use trial as a real study stores it, written straight into the database: ticks
without simulation truth, the experimenter's lift segments (labelled and one still
unlabelled) and gait markers, with known answers."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from sqlalchemy import Engine, insert
from sqlalchemy.orm import Session

from backend.db.evidence_tables import Trial, TrialSegment
from backend.db.lab import Marker
from backend.db.models import Run, ticks_table
from controller.tick_record import Action
from tests.controller.evaluation.tick_builder import TickBuilder

N_TICKS = 4000
#: The walking bout the markers give: ticks 2500..3499 (device time 25.0 .. 34.99 s).
WALK_START, WALK_END = 2500, 3499
UNLABELLED = (2300, 2399)


@dataclass(frozen=True)
class LongUseTrial:
    """What a seeded trial holds."""

    trial_id: int
    correct: int
    missed: int
    walking_locks: int

    @property
    def walking_hours(self) -> float:
        return (WALK_END - WALK_START) * 0.01 / 3600

    @property
    def hours(self) -> float:
        return N_TICKS * 0.01 / 3600


def add_long_use_trial(engine: Engine, session_id: int, correct: int, missed: int,
                       walking_locks: int, controller: str = "umc") -> LongUseTrial:
    """A completed long-use trial of `controller`: `correct` squats recognised and
    locked (both sides 0.3 s after onset), then `missed` squats with neither, a lift
    segment left unlabelled, and a walking bout (marker "walking" to marker
    "standing") with `walking_locks` right-side locks."""
    assert correct + missed <= 10 and walking_locks <= 9
    b = TickBuilder(N_TICKS)
    b.cols["truth_activity"][:] = ""  # a real study: no simulation truth
    segments = []
    for i in range(correct + missed):
        start, end = 100 + 200 * i, 199 + 200 * i
        segments.append((start, start + 40, end, "squat"))
        if i < correct:
            b.posterior(start + 20, "squat", 0.9)
            b.run(start + 30, Action.LOCK_BOTH)
    for j in range(walking_locks):
        b.run(WALK_START + 100 + 100 * j, Action.LOCK_RIGHT)
    b.run(WALK_END + 200, Action.NO_LOCK)
    cols = b.columns()
    with Session(engine) as db:
        run = Run(device_kind="sim", controller=controller, tick_count=N_TICKS)
        db.add(run)
        db.flush()
        trial = Trial(session_id=session_id, controller=controller, task="long_use",
                      planned_order=0, status="completed", run_id=run.id,
                      tick_count=N_TICKS, quality_flags={})
        db.add(trial)
        db.flush()
        rows = []
        for k in range(N_TICKS):
            row: dict[str, object] = {"run_id": run.id}
            for name, col in cols.items():
                v = col[k].item() if isinstance(col[k], np.generic) else col[k]
                row[name] = None if isinstance(v, float) and math.isnan(v) else v
            rows.append(row)
        db.execute(insert(ticks_table), rows)
        for start, peak, end, label in [*segments, (UNLABELLED[0], UNLABELLED[0] + 40,
                                                    UNLABELLED[1], "unlabelled")]:
            db.add(TrialSegment(trial_id=trial.id, start=start, peak=peak, end=end,
                                label=label, source="edited"))
        for t, label in ((0.0, "trial_start"), (WALK_START / 100, "walking"),
                         ((WALK_END + 1) / 100, "standing")):
            db.add(Marker(session_id=session_id, trial_id=trial.id, run_id=run.id, t=t,
                          label=label, source="system" if label == "trial_start"
                          else "console"))
        db.commit()
        return LongUseTrial(trial.id, correct, missed, walking_locks)
