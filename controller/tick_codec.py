"""The one tick codec: a `TickRecord` as a packed block, a database row, JSON and CSV,
and back again.

The fields and their types are `TickRecord`'s (`controller.tick_record`); this module only
says how each kind of value travels:

- **Block** (`TICK_DTYPE`): ticks packed as one numpy structured array, a row per tick.
  This is what crosses the worker/server process boundary (`TickBatch.ticks`): it
  pickles as one buffer, where a tuple of records pickled and unpickled one dataclass
  at a time (the server's biggest cost in a sped-up study). A block is also a set of
  columns: `block["q_left"]` is a view, no copy.
- **Database row**: a tuple in `FIELD_NAMES` order.
- **JSON**: columns `field -> list`, `null` where a value is absent.
- **CSV**: a header of field names, one row per tick; booleans 0/1, an empty cell
  where a value is absent.

One NULL rule for all of them. Writing, NaN ("not computed at this tick") is the only
value that becomes absent: SQL NULL, an empty CSV cell, JSON `null`. Reading, an absent
value becomes the value a `TickRecord` has when that field is not given (`NULL_VALUES`):
NaN for a float, the field's default otherwise (0 for counts and bit sets, False, ""
for the activity, -1 for `truth_lift`, 1 (no lock) for `action`); of the two fields
without a default, `t` reads back as NaN and `seq` as -1 (no sequence number).
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import IO, Any, TypeAlias

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.tick_record import TickColumns, TickRecord

FIELD_NAMES: tuple[str, ...] = TickRecord.field_names()
#: Field name to its kind: "int", "float", "bool" or "str".
FIELD_KINDS: dict[str, str] = {n: t.__name__ for n, t in TickRecord.field_types().items()}
#: Longest string a tick holds (the activity names); the database column is as wide.
STR_WIDTH = 32
_NUMPY_TYPE = {"int": "<i8", "float": "<f8", "bool": "?", "str": f"<U{STR_WIDTH}"}
#: One tick as a row of a numpy structured array, fields in `FIELD_NAMES` order.
TICK_DTYPE = np.dtype([(n, _NUMPY_TYPE[FIELD_KINDS[n]]) for n in FIELD_NAMES])
#: Ticks packed by `pack`: a 1-D array of `TICK_DTYPE`.
TickBlock: TypeAlias = NDArray[np.void]


def _null_value(f: dataclasses.Field[Any]) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    return math.nan if FIELD_KINDS[f.name] == "float" else -1


#: What an absent value (NULL, empty cell, null) reads back as, per field.
NULL_VALUES: dict[str, Any] = {f.name: _null_value(f) for f in dataclasses.fields(TickRecord)}
_FLOAT_INDEX = tuple(i for i, n in enumerate(FIELD_NAMES) if FIELD_KINDS[n] == "float")


# ------------------------------------------------------------------------ blocks


def pack(records: Iterable[TickRecord]) -> TickBlock:
    """Records to a block (in order)."""
    return np.array([r.as_tuple() for r in records], dtype=TICK_DTYPE)


def empty_block(n: int = 0) -> TickBlock:
    """`n` ticks holding every field's `NULL_VALUES` value."""
    block = np.empty(n, dtype=TICK_DTYPE)
    for name in FIELD_NAMES:
        block[name] = NULL_VALUES[name]
    return block


def pack_columns(cols: Mapping[str, ArrayLike]) -> TickBlock:
    """Columns (all of equal length) to a block; a field not given holds its
    `NULL_VALUES` value. Names that are not tick fields are ignored."""
    present = [n for n in FIELD_NAMES if n in cols]
    n = len(np.asarray(cols[present[0]])) if present else 0
    block = empty_block(n)
    for name in present:
        block[name] = cols[name]
    return block


def unpack(block: TickBlock) -> list[TickRecord]:
    """A block back to records, equal (`==`) to the records it was packed from."""
    rows = block.tolist()
    if not _FLOAT_INDEX:
        return [TickRecord(*row) for row in rows]
    out = []
    nan = math.nan
    for row in rows:
        # NaN becomes the `math.nan` singleton the record defaults use, so records
        # compare equal to records built field by field (NaN != NaN otherwise).
        vals = list(row)
        for i in _FLOAT_INDEX:
            if vals[i] != vals[i]:
                vals[i] = nan
        out.append(TickRecord(*vals))
    return out


def columns(block: TickBlock, names: Sequence[str] | None = None) -> TickColumns:
    """A block as columns, `names` or every field (contiguous copies: a field of a
    structured array is a strided view, which compiled kernels do not take)."""
    return {n: np.ascontiguousarray(block[n]) for n in (names or FIELD_NAMES)}


def records_from_columns(cols: Mapping[str, ArrayLike]) -> list[TickRecord]:
    """Columns (a batch replay's output) to records; the inverse of
    `columns_from_records`."""
    return unpack(pack_columns(cols))


def columns_from_records(records: Iterable[TickRecord]) -> TickColumns:
    """Records to columns."""
    return columns(pack(records))


# ----------------------------------------------------------------------- database


def db_rows(block: TickBlock, nan_as_null: bool = True) -> list[tuple[Any, ...]]:
    """Rows for an INSERT of every field in `FIELD_NAMES` order, as Python values.

    NaN becomes None (NULL). SQLite stores a bound NaN as NULL by itself, so a caller
    writing to SQLite may pass `nan_as_null=False` and save the per-value pass."""
    rows: list[tuple[Any, ...]] = block.tolist()
    if not nan_as_null:
        return rows
    out = []
    for row in rows:
        vals = list(row)
        for i in _FLOAT_INDEX:
            if vals[i] != vals[i]:
                vals[i] = None
        out.append(tuple(vals))
    return out


def column_from_values(name: str, values: Sequence[Any]) -> NDArray[Any]:
    """One field's values as read back (None for NULL) to a typed array, by the NULL
    rule. Raises `KeyError` for a name that is not a tick field."""
    kind = FIELD_KINDS[name]
    null = NULL_VALUES[name]
    if kind == "float":
        # numpy turns None into NaN, the float fields' null value.
        return np.array(values, dtype=np.float64)
    if kind == "str":
        return np.array(["" if v is None else v for v in values], dtype=f"<U{STR_WIDTH}")
    if None in values:
        values = [null if v is None else v for v in values]
    ints = np.array(values, dtype=np.int64)  # from Python ints (0/1 for booleans) at C speed
    return ints if kind == "int" else ints != 0


def columns_from_rows(rows: Sequence[Sequence[Any]], names: Sequence[str]) -> TickColumns:
    """Rows of the fields `names` (as a database driver returns them, None for NULL)
    to typed columns."""
    if not rows:
        return {n: column_from_values(n, []) for n in names}
    if len(names) == 1:
        return {names[0]: column_from_values(names[0], [r[0] for r in rows])}
    return {n: column_from_values(n, list(vals))
            for n, vals in zip(names, zip(*rows, strict=True), strict=True)}


# --------------------------------------------------------------------------- JSON


def json_columns(cols: Mapping[str, NDArray[Any]] | TickBlock,
                 names: Sequence[str] | None = None) -> dict[str, list[Any]]:
    """Columns as JSON-ready lists (`names`, or every field the columns hold): NaN and
    infinities become None, booleans stay booleans."""
    if isinstance(cols, np.ndarray):
        keys = list(names or FIELD_NAMES)
    else:
        keys = [n for n in (names or FIELD_NAMES) if n in cols]
    out: dict[str, list[Any]] = {}
    for name in keys:
        col = np.asarray(cols[name])
        values = col.tolist()
        if col.dtype.kind == "f":
            bad = ~np.isfinite(col)
            if bad.any():
                for i in np.flatnonzero(bad).tolist():
                    values[i] = None
        out[name] = values
    return out


def columns_from_json(doc: Mapping[str, Sequence[Any]]) -> TickColumns:
    """JSON columns (null where absent) to typed columns; unknown names are ignored."""
    return {n: column_from_values(n, list(v)) for n, v in doc.items() if n in FIELD_KINDS}


# ---------------------------------------------------------------------------- CSV


def write_csv(cols: Mapping[str, NDArray[Any]] | TickBlock, out: IO[str],
              names: Sequence[str] | None = None, header: bool = True) -> int:
    """Write ticks (a block or columns) as CSV, `names` or every field, after a header
    row of the names unless `header` is False (a later chunk); returns rows.

    Floats are written as `repr` writes them (shortest round-trip form), NaN as an
    empty cell, booleans as 0/1."""
    keys = list(names or FIELD_NAMES)
    cells: list[list[Any]] = []
    for name in keys:
        col = np.asarray(cols[name])
        if col.dtype == np.bool_:
            cells.append(col.astype(np.int64).tolist())
        elif col.dtype.kind == "f":
            values = col.tolist()
            nan = np.isnan(col)
            if nan.any():
                for i in np.flatnonzero(nan).tolist():
                    values[i] = ""
            cells.append(values)
        else:
            cells.append(col.tolist())
    w = csv.writer(out, lineterminator="\n")
    if header:
        w.writerow(keys)
    w.writerows(zip(*cells, strict=True))
    return len(cells[0]) if cells else 0


#: Fields whose absent value is not an empty CSV cell (it reads back as its
#: `NULL_VALUES` value, which `write_csv` writes).
NON_FLOAT_FIELDS: tuple[str, ...] = tuple(n for n in FIELD_NAMES if FIELD_KINDS[n] != "float")


def write_ready_rows_csv(rows: Sequence[Sequence[Any]], out: IO[str]) -> int:
    """Rows of every field (`FIELD_NAMES` order) that are already in CSV form, written
    as they are, without building columns (the export's hot path). Already in CSV form
    means: None only in float fields, booleans as 0/1, floats as Python floats (what
    SQLite returns for ticks the recorder wrote). For such rows this is the text
    `write_csv` writes for `columns_from_rows(rows, FIELD_NAMES)`; the caller checks
    the condition (`backend.analysis.tick_queries.csv_text` asks the database). No header."""
    csv.writer(out, lineterminator="\n").writerows(rows)
    return len(rows)


def write_records_csv(records: Iterable[TickRecord], out: IO[str],
                      names: Sequence[str] | None = None) -> int:
    """Write records as CSV (the text `write_csv` gives for their block)."""
    return write_csv(pack(records), out, names)


_TRUE = frozenset({"1", "true", "t", "yes", "y"})
_FALSE = frozenset({"0", "false", "f", "no", "n"})


def _csv_value(name: str, kind: str, cell: str, row: int) -> Any:
    cell = cell.strip()
    if cell == "":
        return None
    try:
        if kind == "float":
            return float(cell)
        if kind == "int":
            return int(cell)
        if kind == "bool":
            low = cell.lower()
            if low in _TRUE:
                return True
            if low in _FALSE:
                return False
            raise ValueError
    except ValueError:
        raise ValueError(f"row {row}, column {name}: {cell!r} is not a {kind}") from None
    return cell


def read_csv(src: IO[str]) -> TickColumns:
    """CSV written by `write_csv` (or any CSV whose header names tick fields) back to
    typed columns by the NULL rule; columns that are not tick fields are ignored.
    Raises `ValueError` naming the row and column of a value that is not its type."""
    reader = csv.reader(src)
    header = next(reader, None)
    if header is None:
        return {}
    keep = [(j, h.strip()) for j, h in enumerate(header) if h.strip() in FIELD_KINDS]
    values: dict[str, list[Any]] = {n: [] for _, n in keep}
    for row_no, row in enumerate(reader, start=2):
        for j, name in keep:
            cell = row[j] if j < len(row) else ""
            values[name].append(_csv_value(name, FIELD_KINDS[name], cell, row_no))
    return {n: column_from_values(n, v) for n, v in values.items()}
