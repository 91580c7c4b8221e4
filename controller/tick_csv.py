"""Tick records as CSV: one header row of `TickRecord` field names, one row per tick.

NaN (not computed at this tick) is written as an empty cell; booleans as 0/1.
`write_ticks_csv` takes records, `write_columns_csv` the columns of a batch replay.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Sequence
from typing import IO, Any

import numpy as np

from controller.tick import TickColumns, TickRecord


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


def write_columns_csv(cols: TickColumns, out: IO[str]) -> int:
    """Write ticks given as columns (`TickColumns`); the same text `write_ticks_csv`
    writes for the same records, built a column at a time. Returns rows."""
    names = TickRecord.field_names()
    cells: list[list[Any]] = []
    for name in names:
        col = np.asarray(cols[name])
        if col.dtype == np.bool_:
            cells.append(col.astype(np.int64).tolist())
        elif col.dtype.kind == "f":
            nan = np.isnan(col)
            v = col.tolist()
            if nan.any():
                # str(float) is repr(float): csv writes the other cells as `_cell` would.
                v = ["" if m else x for x, m in zip(v, nan.tolist(), strict=True)]
            cells.append(v)
        else:
            cells.append(col.tolist())
    w = csv.writer(out, lineterminator="\n")
    w.writerow(names)
    n = len(cells[0]) if cells else 0
    w.writerows(zip(*cells, strict=True))
    return n
