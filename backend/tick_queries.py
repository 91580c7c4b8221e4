"""Reading stored ticks back: as numpy columns for analysis, as CSV for export.

Plain SQL over the tick table in id order; the columns are `TickRecord`'s fields.
"""

from __future__ import annotations

import io
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Connection, Engine, select

from backend.db.models import ticks_table
from controller.tick import TickRecord
from controller.tick_csv import write_ticks_csv

FIELDS = TickRecord.field_names()
_TYPES = {f: t for f, t in TickRecord.__annotations__.items()}


def _query(run_id: int, first_id: int | None, last_id: int | None) -> Any:
    q = select(*(ticks_table.c[f] for f in FIELDS)).where(ticks_table.c.run_id == run_id)
    if first_id is not None:
        q = q.where(ticks_table.c.id >= first_id)
    if last_id is not None:
        q = q.where(ticks_table.c.id <= last_id)
    return q.order_by(ticks_table.c.id)


def iter_rows(conn: Connection, run_id: int, first_id: int | None = None,
              last_id: int | None = None) -> Iterator[Sequence[Any]]:
    """Rows in `TickRecord.field_names()` order (NULL for values not computed)."""
    yield from conn.execute(_query(run_id, first_id, last_id))


def columns(engine: Engine, run_id: int, first_id: int | None = None,
            last_id: int | None = None) -> dict[str, NDArray[Any]]:
    """A run's ticks as one array per field; NULL floats become NaN."""
    with engine.connect() as conn:
        rows = list(iter_rows(conn, run_id, first_id, last_id))
    out: dict[str, NDArray[Any]] = {}
    for i, f in enumerate(FIELDS):
        kind = _TYPES[f]
        vals = [r[i] for r in rows]
        if kind == "float":
            out[f] = np.array([np.nan if v is None else v for v in vals], dtype=np.float64)
        elif kind == "bool":
            out[f] = np.array([bool(v) for v in vals], dtype=np.bool_)
        elif kind == "int":
            out[f] = np.array([0 if v is None else v for v in vals], dtype=np.int64)
        else:
            out[f] = np.array(["" if v is None else v for v in vals], dtype=object)
    return out


def _cells(row: Sequence[Any]) -> list[Any]:
    return [float("nan") if v is None else v for v in row]


def csv_text(engine: Engine, run_id: int, first_id: int | None = None,
             last_id: int | None = None) -> str:
    """A run's ticks as CSV (header of field names; empty cell where not computed)."""
    buf = io.StringIO()
    with engine.connect() as conn:
        write_ticks_csv((_cells(r) for r in iter_rows(conn, run_id, first_id, last_id)), buf)
    return buf.getvalue()


def tick_id_range(engine: Engine, run_id: int) -> tuple[int | None, int | None]:
    """First and last stored tick id of a run."""
    from sqlalchemy import func

    with engine.connect() as conn:
        lo, hi = conn.execute(
            select(func.min(ticks_table.c.id), func.max(ticks_table.c.id))
            .where(ticks_table.c.run_id == run_id)
        ).one()
    return lo, hi
