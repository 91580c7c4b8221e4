"""The tick codec: every form (block, database row, JSON, CSV) round-trips a record,
and an absent value reads back the same way from each of them (one NULL rule)."""

from __future__ import annotations

import dataclasses
import io
import json
import math
import pickle
import string
from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.evaluation.columns import TickData
from controller.tick_codec import (
    FIELD_NAMES,
    NULL_VALUES,
    TICK_DTYPE,
    columns,
    columns_from_json,
    columns_from_rows,
    db_rows,
    json_columns,
    pack,
    read_csv,
    unpack,
    write_csv,
    write_records_csv,
)
from controller.tick_record import TickRecord

_TYPES = TickRecord.field_types()
_FINITE = st.floats(allow_nan=False, allow_infinity=False, width=64)
_VALUE = {int: st.integers(-2**40, 2**40), float: st.one_of(_FINITE, st.just(math.nan)),
          bool: st.booleans(), str: st.text(string.ascii_letters + "_", max_size=12)}
_RECORD = st.fixed_dictionaries({n: _VALUE[t] for n, t in _TYPES.items()}).map(
    lambda v: TickRecord(**v))


def _same(a: Any, b: Any) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and a != a and b != b)


def _assert_columns_equal(got: dict[str, Any], records: list[TickRecord]) -> None:
    for name in FIELD_NAMES:
        want = [getattr(r, name) for r in records]
        have = np.asarray(got[name]).tolist()
        assert all(_same(h, w) for h, w in zip(have, want, strict=True)), name


@settings(max_examples=40, deadline=None)
@given(st.lists(_RECORD, min_size=1, max_size=5))
def test_block_pickle_db_json_and_csv_round_trip(records: list[TickRecord]) -> None:
    block = pickle.loads(pickle.dumps(pack(records)))  # as across the process boundary
    assert block.dtype == TICK_DTYPE
    assert unpack(block) == records  # NaN is the record's own NaN again, so == holds
    rows = db_rows(block)
    assert all(v is not None or _TYPES[n] is float
               for row in rows for n, v in zip(FIELD_NAMES, row, strict=True))
    _assert_columns_equal(columns_from_rows(rows, FIELD_NAMES), records)
    doc = json.loads(json.dumps(json_columns(block), allow_nan=False))
    _assert_columns_equal(columns_from_json(doc), records)
    text = io.StringIO()
    assert write_csv(block, text) == len(records)
    _assert_columns_equal(read_csv(io.StringIO(text.getvalue())), records)
    again = io.StringIO()
    write_records_csv(records, again)
    assert again.getvalue() == text.getvalue()


def test_one_null_rule_for_rows_json_and_csv() -> None:
    """SQL NULL, JSON null and an empty CSV cell all read back as the value a record
    has when the field is not given (the record's defaults, written out here)."""
    expected = {"seq": -1, "t": math.nan, "count_left_output": 0, "truth_lift": -1,
                "truth_activity": "", "action": 1, "lock_left": False, "flags": 0,
                "plausibility": 0, "q_left": math.nan, "l_squat": 0}
    for name, value in expected.items():
        assert _same(NULL_VALUES[name], value), name
    defaults = {f.name: f.default for f in dataclasses.fields(TickRecord)
                if f.default is not dataclasses.MISSING}
    assert all(_same(NULL_VALUES[n], v) for n, v in defaults.items())

    names = list(expected)
    from_rows = columns_from_rows([tuple(None for _ in names)], names)
    from_json = columns_from_json({n: [None] for n in names})
    from_csv = read_csv(io.StringIO(",".join(names) + "\n" + "," * (len(names) - 1) + "\n"))
    # What the evaluation reads from the database's own None values (an object column).
    from_eval = TickData({n: np.array([None], dtype=object) for n in names})
    for name, value in expected.items():
        for source, cols in (("rows", from_rows), ("json", from_json), ("csv", from_csv)):
            assert _same(cols[name].tolist()[0], value), (source, name)
        if _TYPES[name] is int:
            assert from_eval.int_(name).tolist() == [value], name


def test_csv_writes_empty_cells_for_nan_and_0_1_for_booleans() -> None:
    r = TickRecord(seq=3, t=0.03, lock_left=True, truth_activity="squat")
    out = io.StringIO()
    write_csv(columns(pack([r]), ["seq", "t", "q_left", "lock_left", "truth_activity"]), out,
              ["seq", "t", "q_left", "lock_left", "truth_activity"])
    assert out.getvalue() == "seq,t,q_left,lock_left,truth_activity\n3,0.03,,1,squat\n"


def test_a_cell_that_is_not_its_type_is_named() -> None:
    bad = io.StringIO("seq,lock_left\n1,1\n2,maybe\n")
    try:
        read_csv(bad)
    except ValueError as exc:
        assert "row 3, column lock_left" in str(exc)
    else:
        raise AssertionError("a boolean cell 'maybe' was accepted")


def test_on_demand_columns_are_read_once_and_only_when_used() -> None:
    records = [TickRecord(seq=k, t=k / 100, q_left=k * 0.1, lock_left=k % 2 == 1)
               for k in range(6)]
    full = columns(pack(records))
    asked: list[str] = []

    def load(name: str) -> Any:
        asked.append(name)
        return full[name]

    lazy = TickData.on_demand(6, FIELD_NAMES, load)
    assert len(lazy) == 6 and "q_left" in lazy and asked == []
    assert lazy.float_("q_left").tolist() == full["q_left"].tolist()
    assert lazy.bool_("lock_left").tolist() == [False, True] * 3
    lazy.float_("q_left")
    assert asked == ["q_left", "lock_left"]
    part = lazy.select(2, 4)
    assert part.int_("seq").tolist() == [2, 3] and asked[-1] == "seq"
    changed = lazy.with_columns({"truth_lift": [0, 0, 1, 1, -1, -1]})
    assert changed.int_("truth_lift").tolist() == [0, 0, 1, 1, -1, -1]
    assert "truth_lift" not in asked
