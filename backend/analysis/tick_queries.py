"""Reading stored ticks back: as numpy columns for analysis, as CSV for export.

Plain SQL over the tick table in id order; the columns are `TickRecord`'s fields, and
every value read goes through `controller.tick_codec` (one NULL rule). A caller that
needs a few fields names them: a 10-minute trial is 60,000 rows, and an output that
reads 3 of the 55 columns reads a twentieth of the values.

Every reader takes an engine or a connection. A request that already holds a
connection (its session's, `Session.connection()`) passes that one: a request then
uses one pooled connection, never a second while holding the first (with many
requests at once, each holding one and waiting for another, the pool runs dry).
"""

from __future__ import annotations

import io
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext
from typing import Any

from numpy.typing import NDArray
from sqlalchemy import Connection, Engine, func, select, text

from backend.db.models import ticks_table
from controller.evaluation.columns import TickData
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

#: Where ticks are read from: an engine (a connection of its own per read) or a
#: connection the caller already holds.
Bind = Engine | Connection


@contextmanager
def _driver(bind: Bind) -> Iterator[Any]:
    """The driver's own connection: the caller's (left open) or one from the pool."""
    if isinstance(bind, Connection):
        yield bind.connection.driver_connection
        return
    conn = bind.raw_connection()
    try:
        yield conn
    finally:
        conn.close()


def _connect(bind: Bind) -> Any:
    """A context giving a SQLAlchemy connection: the caller's, or a new one."""
    return nullcontext(bind) if isinstance(bind, Connection) else bind.connect()


def _sql(engine: Bind, names: Sequence[str], first_id: int | None,
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


def columns(engine: Bind, run_id: int, first_id: int | None = None,
            last_id: int | None = None,
            fields: Sequence[str] | None = None) -> dict[str, NDArray[Any]]:
    """A run's ticks (ids `first_id..last_id` if given) as one typed array per field,
    `fields` or all of them; NULL reads back by the codec's rule (`NULL_VALUES`).
    Raises `ValueError` naming a field that is not a tick field."""
    names = tuple(fields) if fields is not None else FIELD_NAMES
    sql, params = _sql(engine, names, first_id, last_id)
    # The driver's own cursor: SQLAlchemy's result rows cost more than the query.
    with _driver(engine) as conn:
        cur = conn.cursor()
        cur.execute(sql, (run_id, *params))
        rows = cur.fetchall()
        cur.close()
    return columns_from_rows(rows, names)


def run_ticks(bind: Bind, run_id: int | None, fields: Sequence[str] = ()) -> TickData:
    """A run's stored ticks as checked columns, up to the last tick stored now (so every
    column has the same ticks); empty without a run.

    `t` and `fields` (what the caller will read) are read at once; every other field
    when first needed. SQLite reads a whole row to get one of its values, so each
    column read on its own costs nearly a scan of the run: the dozen fields a trial's
    evaluation reads cost a quarter as much in one query as one by one. Raises
    `ValueError` naming a field of `fields` that is not a tick field."""
    if run_id is None:
        return TickData({})
    last = tick_id_range(bind, run_id)[1]
    if last is None:
        return TickData({})
    first = columns(bind, run_id, last_id=last, fields=tuple(dict.fromkeys(("t", *fields))))
    return TickData.on_demand(
        len(first["t"]), FIELD_NAMES,
        lambda name: columns(bind, run_id, last_id=last, fields=(name,))[name],
    ).with_columns(first)


def csv_text(engine: Bind, run_id: int, first_id: int | None = None,
             last_id: int | None = None) -> str:
    """A run's ticks as CSV (header of field names; empty cell where not computed), in
    the codec's CSV form, read and written a chunk of rows at a time."""
    sql, params = _sql(engine, FIELD_NAMES, first_id, last_id)
    ready = engine.dialect.name == "sqlite" and not _null_outside_floats(
        engine, run_id, first_id, last_id)
    buf = io.StringIO()
    with _driver(engine) as conn:
        cur = conn.cursor()
        cur.execute(sql, (run_id, *params))
        write_csv(columns_from_rows([], FIELD_NAMES), buf)  # the header
        while part := cur.fetchmany(_CHUNK):
            if ready:  # the driver's rows are the codec's CSV already
                write_ready_rows_csv(part, buf)
            else:
                write_csv(columns_from_rows(part, FIELD_NAMES), buf, header=False)
        cur.close()
    return buf.getvalue()


def _null_outside_floats(engine: Bind, run_id: int, first_id: int | None,
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
    with _connect(engine) as conn:
        return bool(conn.execute(q).scalar_one())


def tick_id_range(engine: Bind, run_id: int) -> tuple[int | None, int | None]:
    """First and last stored tick id of a run."""
    with _connect(engine) as conn:
        lo, hi = conn.execute(
            select(func.min(ticks_table.c.id), func.max(ticks_table.c.id))
            .where(ticks_table.c.run_id == run_id)
        ).one()
    return lo, hi


def count(engine: Bind, run_id: int) -> int:
    """How many ticks a run has stored."""
    with _connect(engine) as conn:
        return int(conn.execute(select(func.count()).select_from(ticks_table)
                                .where(ticks_table.c.run_id == run_id)).scalar_one())
