"""Reading stored ticks back: as numpy columns for analysis, as CSV for export.

Plain SQL over the tick table in id order; the columns are `TickRecord`'s fields.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Connection, Engine, select, text

from backend.db.models import ticks_table
from controller.tick import TickRecord

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


_BOOL_INDEX = [i for i, f in enumerate(FIELDS) if _TYPES[f] == "bool"]


def csv_text(engine: Engine, run_id: int, first_id: int | None = None,
             last_id: int | None = None) -> str:
    """A run's ticks as CSV (header of field names; empty cell where not computed).

    This is the export hot path (60,000 ticks for a 10-minute trial): rows go from the
    driver to `csv.writer` in chunks without per-value Python work. NULL is written as
    an empty cell by the csv module itself; SQLite stores booleans as 0/1 already, other
    databases get them converted.
    """
    cols = ", ".join(f'"{f}"' for f in FIELDS)
    sql = f"SELECT {cols} FROM ticks WHERE run_id = :run"
    params: dict[str, int] = {"run": run_id}
    if first_id is not None:
        sql += " AND id >= :first"
        params["first"] = first_id
    if last_id is not None:
        sql += " AND id <= :last"
        params["last"] = last_id
    sql += " ORDER BY id"
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(FIELDS)
    with engine.connect() as conn:
        convert = conn.dialect.name != "sqlite"
        result = conn.execute(text(sql), params)
        while True:
            part = result.fetchmany(5000)
            if not part:
                break
            if convert:
                w.writerows(_as_csv_row(r) for r in part)
            else:
                w.writerows(part)
    return buf.getvalue()


def _as_csv_row(row: Sequence[Any]) -> list[Any]:
    out = list(row)
    for i in _BOOL_INDEX:
        if out[i] is not None:
            out[i] = int(out[i])
    return out


def tick_id_range(engine: Engine, run_id: int) -> tuple[int | None, int | None]:
    """First and last stored tick id of a run."""
    from sqlalchemy import func

    with engine.connect() as conn:
        lo, hi = conn.execute(
            select(func.min(ticks_table.c.id), func.max(ticks_table.c.id))
            .where(ticks_table.c.run_id == run_id)
        ).one()
    return lo, hi


def count(engine: Engine, run_id: int) -> int:
    """How many ticks a run has stored."""
    from sqlalchemy import func

    with engine.connect() as conn:
        return int(conn.execute(select(func.count()).select_from(ticks_table)
                                .where(ticks_table.c.run_id == run_id)).scalar_one())
