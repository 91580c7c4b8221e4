"""Quality flags of a trial's data, from the device's own clock.

The device stamps every sample with its time (`t`, one sample per `SAMPLE_PERIOD_S`). A step
longer than `GAP_FACTOR` periods means samples never arrived (a gap); a step of zero or
less means the device clock went backwards (the device process restarted, or replayed
old samples). Either makes the trial's timing unreliable, so the trial and the study
results carry the flags instead of hiding the hole.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.device.base import SAMPLE_PERIOD_S

#: A step of more than 1.5 periods cannot be jitter of the device clock (which counts
#: whole periods): at least one sample is missing.
GAP_FACTOR = 1.5


def assess(t: NDArray[Any], period_s: float = SAMPLE_PERIOD_S) -> dict[str, Any]:
    """Flags for a trial whose device times are `t` (in stored order); {} when clean.

    Keys, when present: `time_gaps` (count), `missing_s` (device time skipped over in
    gaps, minus the one period a normal step takes), `largest_gap_s`, `time_backwards`
    (count), `largest_backstep_s` (how far the clock went back, positive)."""
    t = np.asarray(t, dtype=np.float64)
    t = t[np.isfinite(t)]
    if t.size < 2:
        return {}
    dt = np.diff(t)
    out: dict[str, Any] = {}
    gaps = dt[dt > GAP_FACTOR * period_s]
    if gaps.size:
        out["time_gaps"] = int(gaps.size)
        out["missing_s"] = round(float(np.sum(gaps - period_s)), 6)
        out["largest_gap_s"] = round(float(gaps.max()), 6)
    back = dt[dt <= 0.0]
    if back.size:
        out["time_backwards"] = int(back.size)
        out["largest_backstep_s"] = round(float(-back.min()), 6)
    return out


def describe(flags: dict[str, Any] | None) -> str:
    """One line for tables and notes; "" when clean."""
    if not flags:
        return ""
    parts = []
    if flags.get("time_gaps"):
        parts.append(f"{flags['time_gaps']} device time gap(s), "
                     f"{flags.get('missing_s', 0.0):.2f} s missing")
    if flags.get("time_backwards"):
        parts.append(f"device time went backwards {flags['time_backwards']} time(s) "
                     f"(by up to {flags.get('largest_backstep_s', 0.0):.2f} s)")
    return "; ".join(parts)
