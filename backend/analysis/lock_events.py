"""Lock events of a trial, derived from its ticks: when each side's solenoid command went
on and off, when the ratchet engaged and released, and the peak torque of each
engagement. Computed once when the trial stops and stored for quick listing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class LockEventRow:
    """One event."""

    t: float
    side: str
    kind: str
    torque_peak: float | None = None


#: The tick fields `derive` reads (a caller reads only these from the database).
TICK_FIELDS = ("t", "lock_left", "lock_right", "locked_left", "locked_right",
               "torque_left", "torque_right")


def derive(cols: dict[str, NDArray[np.generic]]) -> list[LockEventRow]:
    """Events from tick columns (`TICK_FIELDS`)."""
    t = np.asarray(cols["t"], dtype=np.float64)
    out: list[LockEventRow] = []
    for side in ("left", "right"):
        cmd = np.asarray(cols[f"lock_{side}"], dtype=bool)
        locked = np.asarray(cols[f"locked_{side}"], dtype=bool)
        torque = np.nan_to_num(np.asarray(cols[f"torque_{side}"], dtype=np.float64))
        for i in np.flatnonzero(np.diff(cmd.astype(np.int8)) != 0) + 1:
            out.append(LockEventRow(float(t[i]), side, "command_on" if cmd[i] else "command_off"))
        edges = np.flatnonzero(np.diff(locked.astype(np.int8)) != 0) + 1
        starts = [int(i) for i in edges if locked[i]]
        if locked.size and locked[0]:
            starts.insert(0, 0)
        for s in starts:
            after = np.flatnonzero(~locked[s:])
            e = s + int(after[0]) if after.size else locked.size
            out.append(LockEventRow(float(t[s]), side, "engaged", float(torque[s:e].max())))
            if e < locked.size:
                out.append(LockEventRow(float(t[e]), side, "released"))
    out.sort(key=lambda ev: (ev.t, ev.side, ev.kind))
    return out
