"""Import a lab's own human motion data (hip angle and torque per motion and leg) from CSV.

Columns: `motion,leg,n,theta_rad,tau_nm` with motion in squat, stoop_left, stoop_right,
walking; leg in left, right; n = 0..100 (progress s = n / 100); torque in Nm, hip
extension positive. Every motion and leg needs all 101 samples. Errors name the row
(1 is the header) and the column.
"""

from __future__ import annotations

import csv
import io
import math
import re

import numpy as np

from controller.human_data import HUMAN_MOTIONS, LEGS, N_PROGRESS, HumanMotionData

COLUMNS = ("motion", "leg", "n", "theta_rad", "tau_nm")

#: What a cell may hold: plain decimals (an optional sign, digits with at most one
#: point, an optional exponent), ASCII only. Python's `int` and `float` also read
#: `1_0` as 10, other scripts' digits, `inf` and `nan`: a typo must not become data.
_INTEGER = re.compile(r"[0-9]+", re.ASCII)
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)


class CsvError(ValueError):
    """A malformed upload; `row` and `column` say where."""

    def __init__(self, row: int, column: str, problem: str) -> None:
        super().__init__(f"row {row}, column {column}: {problem}")
        self.row, self.column, self.problem = row, column, problem


def parse_human_data(text: str, source: str) -> HumanMotionData:
    """Parse and validate; raises `CsvError` at the first problem (also for what the
    csv module itself refuses, such as a field longer than its 128 KiB limit)."""
    reader = csv.DictReader(io.StringIO(text))
    try:
        return _parse(reader, source)
    except csv.Error as exc:
        raise CsvError(reader.line_num, "file", str(exc)) from None


def _parse(reader: csv.DictReader[str], source: str) -> HumanMotionData:
    header = [h.strip() for h in (reader.fieldnames or [])]
    for c in COLUMNS:
        if c not in header:
            raise CsvError(1, c, f"missing column; expected {','.join(COLUMNS)}")
    theta = np.full((len(HUMAN_MOTIONS), len(LEGS), N_PROGRESS), np.nan)
    tau = np.full_like(theta, np.nan)
    for row_no, raw in enumerate(reader, start=2):
        row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}
        motion = row["motion"]
        if motion not in HUMAN_MOTIONS:
            raise CsvError(row_no, "motion", f"{motion!r} is not one of {', '.join(HUMAN_MOTIONS)}")
        leg = row["leg"]
        if leg not in LEGS:
            raise CsvError(row_no, "leg", f"{leg!r} is not left or right")
        if not _INTEGER.fullmatch(row["n"]):
            raise CsvError(row_no, "n", f"not a plain integer (digits only): {row['n']!r}")
        # Bound the digits before int(): it raises ValueError (not CsvError, a 500)
        # beyond 4,300 digits, and any n of more digits than N_PROGRESS is out of range.
        digits = row["n"].lstrip("0")
        n = int(digits or "0") if len(digits) <= len(str(N_PROGRESS)) else N_PROGRESS
        if not 0 <= n < N_PROGRESS:
            raise CsvError(row_no, "n", f"{row['n'][:40]!r} outside 0..{N_PROGRESS - 1}")
        i, j = HUMAN_MOTIONS.index(motion), LEGS.index(leg)
        if not np.isnan(theta[i, j, n]):
            raise CsvError(row_no, "n", f"duplicate sample {motion}/{leg}/n={n}")
        for col, arr, limit in (("theta_rad", theta, 2 * math.pi), ("tau_nm", tau, 1000.0)):
            if not _DECIMAL.fullmatch(row[col]):
                raise CsvError(row_no, col, f"not a plain decimal number such as -0.25 or "
                               f"1.5e-3: {row[col][:40]!r}")
            v = float(row[col])
            if not math.isfinite(v) or abs(v) > limit:
                raise CsvError(row_no, col, f"{v} is not finite or beyond +-{limit:g}")
            arr[i, j, n] = v
    missing = np.argwhere(np.isnan(theta))
    if missing.size:
        i, j, n = missing[0]
        raise CsvError(0, "n", f"missing {len(missing)} samples, first {HUMAN_MOTIONS[i]}/"
                       f"{LEGS[j]}/n={n}; every motion and leg needs n = 0..100")
    return HumanMotionData(theta=theta, tau=tau, source=source, version="imported")
