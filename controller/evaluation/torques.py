"""Exoskeleton torques after the fact, from the recorded spring deflection.

The paper computed its torques a posteriori "using the control signals sent to the
low-level controller and the spring model". The tick already carries that result
(`torque_left/right`, computed by the pipeline from the measured deflection `alpha`
while the side is locked). Recomputing is needed when a recording lacks the torque
columns or when the torques are wanted for another spring setting (the paper notes the
UMC's lower torques "can be compensated for by ... increasing the pretension").
"""

from __future__ import annotations

import math

import numpy as np

from controller.evaluation.columns import Columns, FloatArray, TickData
from controller.lowlevel.actuator import PAPER_ACTUATOR, MaccepaParams, maccepa_torque

#: The pipeline's default: a side counts as locked above this deflection (rad).
DEFAULT_LOCK_DEADBAND = math.radians(0.5)


def recompute_torques(
    columns: Columns,
    precompression_pct: float,
    params: MaccepaParams = PAPER_ACTUATOR,
    lock_deadband: float = DEFAULT_LOCK_DEADBAND,
) -> TickData:
    """The columns with `torque_left/right` recomputed by the actuator model.

    A side produces torque while it is locked: `locked_<side>` when recorded, else a
    deflection above `lock_deadband` (the pipeline's own rule, since a spring can only
    deflect while the ratchet holds it). NaN deflections give NaN torque.

    Args:
        columns: needs `alpha_left`, `alpha_right`; uses `locked_left/right`.
        precompression_pct: spring precompression, percent of the 22 mm maximum.
        params: actuator geometry.
        lock_deadband: deflection (rad) above which a side counts as locked when the
            `locked_*` columns are absent.
    """
    cols = TickData.of(columns)
    data: dict[str, FloatArray] = {}
    for side in ("left", "right"):
        alpha = cols.float_(f"alpha_{side}")
        name = f"locked_{side}"
        locked = cols.bool_(name) if name in cols else alpha > lock_deadband
        ok = np.isfinite(alpha)
        torque: FloatArray = np.where(
            locked, maccepa_torque(np.where(ok, alpha, 0.0), precompression_pct, params), 0.0
        )
        torque[~ok] = math.nan
        data[f"torque_{side}"] = torque
    return cols.with_columns(data)
