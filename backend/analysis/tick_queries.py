"""Reading stored ticks back: as numpy columns for analysis, as CSV for export.

Plain SQL over the tick table in id order; the columns are `TickRecord`'s fields, and
every value read goes through `controller.tick_codec` (one NULL rule). A caller that
needs a few fields names them: a 10-minute trial is 60,000 rows, and an output that
reads 3 of the 55 columns reads a twentieth of the values.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import Any

from numpy.typing import NDArray
from sqlalchemy import Engine, func, select, text

from backend.db.models import ticks_table
from controller.tick_codec import (
    FIELD_KINDS,
    FIELD_NAMES,
    NON_FLOAT_FIELDS,
    columns_from_rows,
    write_csv,
    write_ready_rows_csv,
)

#: Rows fetched from the driver at a time.
_CHUNK = 20_000


def _sql(engine: Engine, names: Sequence[str], first_id: int | None,
         last_id: int | None) -> tuple[str, tuple[Any, ...]]:
    """The driver-level SELECT of `names` of one run in id order, and its parameters
    after the run id."""
    unknown = [n for n in names if n not in FIELD_KINDS]
    if unknown:
        raise ValueError(f"not tick fields: {', '.join(unknown)}")
    mark = "?" if engine.dialect.paramstyle == "qmark" else "%s"
    quote = engine.dialect.identifier_preparer.quote  # "trigger" is a keyword
    sql = (f"SELECT {', '.join(quote(n) for n in names)} FROM {ticks_table.name} "
           f"WHERE run_id = {mark}")
    params: tuple[Any, ...] = ()
    if first_id is not None:
        sql += f" AND id >= {mark}"
        params += (first_id,)
    if last_id is not None:
        sql += f" AND id <= {mark}"
        params += (last_id,)
    return sql + " ORDER BY id", params


def columns(engine: Engine, run_id: int, first_id: int | None = None,
            last_id: int | None = None,
            fields: Sequence[str] | None = None) -> dict[str, NDArray[Any]]:
    """A run's ticks (ids `first_id..last_id` if given) as one typed array per field,
    `fields` or all of them; NULL reads back by the codec's rule (`NULL_VALUES`).
    Raises `ValueError` naming a field that is not a tick field."""
    names = tuple(fields) if fields is not None else FIELD_NAMES
    sql, params = _sql(engine, names, first_id, last_id)
    # The driver's own cursor: SQLAlchemy's result rows cost more than the query.
    conn = engine.raw_connection()
    try:
        cur = conn.cursor()
        cur.execute(sql, (run_id, *params))
        rows = cur.fetchall()
        cur.close()
    finally:
        conn.close()
    return columns_from_rows(rows, names)


def csv_text(engine: Engine, run_id: int, first_id: int | None = None,
             last_id: int | None = None) -> str:
    """A run's ticks as CSV (header of field names; empty cell where not computed), in
    the codec's CSV form, read and written a chunk of rows at a time."""
    sql, params = _sql(engine, FIELD_NAMES, first_id, last_id)
    ready = engine.dialect.name == "sqlite" and not _null_outside_floats(
        engine, run_id, first_id, last_id)
    buf = io.StringIO()
    conn = engine.raw_connection()
    try:
        cur = conn.cursor()
        cur.execute(sql, (run_id, *params))
        write_csv(columns_from_rows([], FIELD_NAMES), buf)  # the header
        while part := cur.fetchmany(_CHUNK):
            if ready:  # the driver's rows are the codec's CSV already
                write_ready_rows_csv(part, buf)
            else:
                write_csv(columns_from_rows(part, FIELD_NAMES), buf, header=False)
        cur.close()
    finally:
        conn.close()
    return buf.getvalue()


def _null_outside_floats(engine: Engine, run_id: int, first_id: int | None,
                         last_id: int | None) -> bool:
    """Whether any stored tick of the range has NULL in a field that is not a float
    (a row an older schema left): those cells need the codec's NULL rule."""
    quote = engine.dialect.identifier_preparer.quote
    cond = " OR ".join(f"{quote(n)} IS NULL" for n in NON_FLOAT_FIELDS)
    q = select(func.count()).select_from(ticks_table).where(
        ticks_table.c.run_id == run_id, text(f"({cond})"))
    if first_id is not None:
        q = q.where(ticks_table.c.id >= first_id)
    if last_id is not None:
        q = q.where(ticks_table.c.id <= last_id)
    with engine.connect() as conn:
        return bool(conn.execute(q).scalar_one())


def tick_id_range(engine: Engine, run_id: int) -> tuple[int | None, int | None]:
    """First and last stored tick id of a run."""
    with engine.connect() as conn:
        lo, hi = conn.execute(
            select(func.min(ticks_table.c.id), func.max(ticks_table.c.id))
            .where(ticks_table.c.run_id == run_id)
        ).one()
    return lo, hi


def count(engine: Engine, run_id: int) -> int:
    """How many ticks a run has stored."""
    with engine.connect() as conn:
        return int(conn.execute(select(func.count()).select_from(ticks_table)
                                .where(ticks_table.c.run_id == run_id)).scalar_one())
