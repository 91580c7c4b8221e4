"""Tick records as CSV: one header row of `TickRecord` field names, one row per tick.

NaN (not computed at this tick) is written as an empty cell; booleans as 0/1.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Sequence
from typing import IO, Any

from controller.tick import TickRecord


def _cell(v: Any) -> Any:
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return v


def write_ticks_csv(
    records: Iterable[TickRecord] | Iterable[Sequence[Any]],
    out: IO[str],
    columns: Sequence[str] | None = None,
) -> int:
    """Write records (or value rows in `TickRecord.field_names()` order); returns rows."""
    names = TickRecord.field_names()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(columns or names)
    index = [names.index(c) for c in columns] if columns else None
    n = 0
    for r in records:
        row = r.as_tuple() if isinstance(r, TickRecord) else tuple(r)
        if index is not None:
            row = tuple(row[i] for i in index)
        w.writerow([_cell(v) for v in row])
        n += 1
    return n
