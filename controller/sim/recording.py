"""True hip angles of a simulated session, in memory or as CSV, without the exoskeleton.

For building motion models, segmentation tests and offline studies: the wearer's true
hip flexion (no donning offset, no sensor noise, no exoskeleton) with ground truth.
Only the trajectory is generated, vectorised, so a whole protocol takes milliseconds.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from controller.sim.biomechanics import FloatArray
from controller.sim.participant import VirtualParticipant
from controller.sim.scripts import get_script, realise

CSV_COLUMNS: tuple[str, ...] = ("t", "theta_left", "theta_right", "activity", "lift_index")


class TruthArrays(NamedTuple):
    """Ground truth per sample: activity name, lift index (-1 outside lifts), progress
    within the lift (NaN outside)."""

    activity: NDArray[np.str_]
    lift_index: NDArray[np.int32]
    progress: FloatArray


class SimulatedAngles(NamedTuple):
    """Times (s), true hip flexion (rad, (K, 2) left/right) and ground truth."""

    t: FloatArray
    q: FloatArray
    truth: TruthArrays


def simulate_angles(
    seed: int, script: str, participant: VirtualParticipant | None = None
) -> SimulatedAngles:
    """One run of `script` by participant `seed` (or the given participant): the same
    trajectory `SimulatedExoskeleton(seed, script)` plays."""
    spec = get_script(script)
    p = participant if participant is not None else VirtualParticipant.from_seed(seed)
    traj = realise(spec, p, seed)
    truth = TruthArrays(traj.activity_names(), traj.lift, traj.progress)
    return SimulatedAngles(traj.t, traj.theta, truth)


def simulate_to_csv(seed: int, script: str, out: Path) -> int:
    """Write `t,theta_left,theta_right,activity,lift_index` (s, rad) for one run of
    `script`; returns the number of data rows."""
    run = simulate_angles(seed, script)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(CSV_COLUMNS)
        rows = zip(
            run.t.tolist(),
            run.q[:, 0].tolist(),
            run.q[:, 1].tolist(),
            run.truth.activity.tolist(),
            run.truth.lift_index.tolist(),
            strict=True,
        )
        for t, left, right, act, lift in rows:
            writer.writerow((f"{t:.2f}", f"{left:.6f}", f"{right:.6f}", act, lift))
    return int(run.t.size)
