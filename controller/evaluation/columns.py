"""Tick data as typed columns: the one input every evaluation function reads.

The backend reads ticks from SQL, the CLI from CSV, a virtual study straight from the
controllers; all three can hand over a mapping `field name -> array` with the field
names of `controller.tick_record.TickRecord`. This module checks that mapping once and gives
typed arrays, so the metrics never guess whether `lock_left` arrived as bools, 0/1
integers or strings from a CSV file.

Columns that a caller did not provide are simply absent; a metric that needs one
raises `ValueError` naming it. Unknown names (a database `id`, a `session_id`) are
ignored rather than rejected, so callers can pass their rows as they are.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import fields
from typing import Any, TypeAlias

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controller.device.base import SAMPLE_PERIOD_S
from controller.tick_codec import column_from_values, columns_from_records
from controller.tick_record import TickRecord

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]
StrArray = NDArray[np.str_]
#: One column as a caller may hold it: an array, or a list with None for SQL NULL.
ColumnLike: TypeAlias = ArrayLike | Sequence[Any]

# TickRecord is declared with `from __future__ import annotations`, so the field
# types are the annotation strings.
_KIND: dict[str, str] = {f.name: str(f.type) for f in fields(TickRecord)}
_TRUE_STRINGS = frozenset({"1", "true", "t", "yes", "y"})


def _to_bool(name: str, raw: ColumnLike) -> BoolArray:
    a = np.asarray(raw)
    if a.dtype.kind in "US":
        return np.asarray([str(x).strip().lower() in _TRUE_STRINGS for x in a], dtype=bool)
    if a.dtype.kind == "O":
        return np.asarray([bool(x) if x is not None else False for x in a], dtype=bool)
    if a.dtype.kind == "f" and np.isnan(a).any():
        raise ValueError(f"boolean column {name!r} contains NaN")
    return a.astype(bool)


def _to_int(name: str, raw: ColumnLike) -> IntArray:
    a = np.asarray(raw)
    if a.dtype.kind == "O":
        # None (SQL NULL) reads back as the codec says, as everywhere else.
        a = column_from_values(name, a.tolist())
    if a.dtype.kind in "US":
        a = a.astype(np.float64)
    if a.dtype.kind == "f":
        if not np.isfinite(a).all():
            raise ValueError(f"integer column {name!r} contains NaN or inf")
        if (a != np.round(a)).any():
            raise ValueError(f"integer column {name!r} contains fractions")
    return a.astype(np.int64)


def _to_float(raw: ColumnLike) -> FloatArray:
    a = np.asarray(raw)
    if a.dtype.kind == "O":
        a = np.asarray([math.nan if x is None else x for x in a])
    if a.dtype.kind in "US":
        a = np.asarray([math.nan if str(x).strip() == "" else float(x) for x in a])
    return np.asarray(a, dtype=np.float64)


def _to_str(raw: ColumnLike) -> StrArray:
    a = np.asarray(raw)
    if a.dtype.kind == "O":
        a = np.asarray(["" if x is None else str(x) for x in a])
    return np.asarray(a, dtype=np.str_)


class TickData:
    """Typed, equal-length tick columns keyed by `TickRecord` field names.

    Accepts `controller.tick_record.TickColumns` (the batch replay's plain dict, strings as
    object arrays), the backend's query result, or any mapping of lists.

    Args:
        data: field name to a 1-D array-like. Only `TickRecord` names are kept.

    Raises:
        ValueError: a column is not 1-D, the columns differ in length, or a value
            cannot be read as its field's type.

    >>> cols = TickData({"t": [0.0, 0.01], "lock_left": [0, 1]})
    >>> len(cols), cols.bool_("lock_left").tolist()
    (2, [False, True])
    """

    def __init__(self, data: Mapping[str, ColumnLike]) -> None:
        self._data: dict[str, np.ndarray[Any, Any]] = {}
        #: Fields not read yet, and how to read one (see `on_demand`).
        self._later: tuple[str, ...] = ()
        self._load: Callable[[str], ColumnLike] | None = None
        self._n: int | None = None
        for name, raw in data.items():
            if name in _KIND:
                self._data[name] = self._checked(name, raw)
        if self._n is None:
            self._n = 0

    def _checked(self, name: str, raw: ColumnLike) -> np.ndarray[Any, Any]:
        kind = _KIND[name]
        if kind == "bool":
            arr: np.ndarray[Any, Any] = _to_bool(name, raw)
        elif kind == "int":
            arr = _to_int(name, raw)
        elif kind == "float":
            arr = _to_float(raw)
        else:
            arr = _to_str(raw)
        if arr.ndim != 1:
            raise ValueError(f"column {name!r} must be 1-D, got shape {arr.shape}")
        if self._n is None:
            self._n = int(arr.shape[0])
        elif arr.shape[0] != self._n:
            raise ValueError(
                f"column {name!r} has {arr.shape[0]} values, the others {self._n}"
            )
        # A read-only view: the caller's own array (kept without a copy when its
        # dtype already fits) must stay writable for the caller.
        arr = arr.view()
        arr.setflags(write=False)
        return arr

    @classmethod
    def on_demand(cls, n: int, names: Iterable[str],
                  load: Callable[[str], ColumnLike]) -> TickData:
        """`n` ticks whose fields `names` are read by `load(name)` when first asked
        for, for a store where one column costs much less than all of them (a stored
        trial is 55 columns, and an output reads a handful)."""
        data = cls({})
        data._n = n
        data._later = tuple(name for name in names if name in _KIND)
        data._load = load
        return data

    @classmethod
    def of(cls, data: TickData | Mapping[str, ColumnLike]) -> TickData:
        """`data` itself if it is already checked, else a checked copy."""
        return data if isinstance(data, TickData) else cls(data)

    def with_columns(self, changes: Mapping[str, ColumnLike]) -> TickData:
        """A copy with `changes` (field name to a column of the same length) instead
        of those fields; fields not read yet stay so."""
        out = TickData({})
        out._n = self._n
        out._data = dict(self._data)
        out._later = tuple(n for n in self._later if n not in changes)
        out._load = self._load
        for name, raw in changes.items():
            if name in _KIND:
                out._data[name] = out._checked(name, raw)
        return out

    @classmethod
    def from_records(cls, records: Sequence[TickRecord]) -> TickData:
        """Columns from tick records, as a controller loop produces them."""
        return cls(columns_from_records(records))

    def __len__(self) -> int:
        return self._n or 0

    def __contains__(self, name: object) -> bool:
        return name in self._data or name in self._later

    @property
    def names(self) -> tuple[str, ...]:
        """The fields present (read or not yet)."""
        return (*self._data, *(n for n in self._later if n not in self._data))

    def _get(self, name: str) -> np.ndarray[Any, Any]:
        try:
            return self._data[name]
        except KeyError:
            if name in self._later and self._load is not None:
                arr = self._checked(name, self._load(name))
                self._data[name] = arr
                return arr
            if name not in _KIND:
                raise ValueError(f"{name!r} is not a TickRecord field") from None
            raise ValueError(f"tick column {name!r} is needed but was not provided") from None

    def float_(self, name: str) -> FloatArray:
        """A float column (NaN = not computed at that tick)."""
        return np.asarray(self._get(name), dtype=np.float64)

    def bool_(self, name: str) -> BoolArray:
        """A boolean column."""
        return np.asarray(self._get(name), dtype=bool)

    def int_(self, name: str) -> IntArray:
        """An integer column."""
        return np.asarray(self._get(name), dtype=np.int64)

    def str_(self, name: str) -> StrArray:
        """A string column."""
        return np.asarray(self._get(name), dtype=np.str_)

    def time(self) -> FloatArray:
        """Device time per tick (s), with gaps filled.

        Bad samples can carry a NaN timestamp; those are interpolated over the tick
        index from their neighbours, so durations stay measured in device time. With
        no usable `t` at all the ticks are assumed `SAMPLE_PERIOD_S` apart from 0.
        """
        idx = np.arange(len(self), dtype=np.float64)
        if "t" not in self:
            return idx * SAMPLE_PERIOD_S
        t = self.float_("t")
        ok = np.isfinite(t)
        if ok.all():
            return t
        if ok.sum() == 0:
            return idx * SAMPLE_PERIOD_S
        if ok.sum() == 1:
            k = int(np.flatnonzero(ok)[0])
            return t[k] + (idx - k) * SAMPLE_PERIOD_S
        return np.asarray(np.interp(idx, idx[ok], t[ok]), dtype=np.float64)

    def select(self, start: int, stop: int) -> TickData:
        """Ticks `start..stop-1` as new columns (for a figure of a stretch)."""
        if not 0 <= start <= stop <= len(self):
            raise ValueError(f"need 0 <= start <= stop <= {len(self)}, got {start}, {stop}")
        return TickData.on_demand(stop - start, self.names,
                                  lambda name: self._get(name)[start:stop])

    def as_dict(self) -> dict[str, np.ndarray[Any, Any]]:
        """The typed columns (read-only arrays), every one read."""
        return {name: self._get(name) for name in self.names}


#: What the public functions accept: checked columns or a plain mapping.
Columns: TypeAlias = TickData | Mapping[str, ColumnLike]
