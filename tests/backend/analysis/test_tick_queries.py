"""Stored ticks read back through the codec: the columns asked for, NULL by its one
rule, and the same values as CSV as the records written; a run's fields read at once
equal to the same fields read one by one."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sqlalchemy import text

from backend.analysis import tick_queries
from backend.db import migrate
from backend.db.engine import make_engine
from backend.live.recorder import TickRecorder
from backend.worker.messages import RunStarted, TickBatch
from controller.evaluation.columns import TickData
from controller.tick_codec import FIELD_NAMES, read_csv, write_records_csv
from controller.tick_record import TickRecord


def test_columns_csv_and_null_read_back_by_the_codec(db_url: str) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    run_id = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
    records = [TickRecord(seq=k, t=k / 100, q_left=0.01 * k, lock_right=k == 2,
                          truth_activity="squat", truth_lift=0, action=2)
               for k in range(4)]
    rec.add(TickBatch.from_records(1, records))
    assert rec.flush() == 4
    # Rows the recorder wrote go to CSV as the driver returns them: the codec's text.
    written = io.StringIO()
    write_records_csv(records, written)
    assert tick_queries.csv_text(engine, run_id) == written.getvalue()
    # A row as an older schema left it: integer and text columns never written (NULL).
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO ticks (run_id, seq, t) VALUES (:r, 4, 0.04)"),
                     {"r": run_id})

    cols = tick_queries.columns(engine, run_id)
    assert list(cols) == list(FIELD_NAMES)
    assert cols["seq"].tolist() == [0, 1, 2, 3, 4]
    assert cols["q_left"][1] == 0.01 and math.isnan(cols["omega_left"][1])
    assert cols["lock_right"].tolist() == [False, False, True, False, False]
    # The NULL row: the values a record has when these fields are not given.
    assert cols["truth_lift"].tolist()[-1] == -1
    assert cols["action"].tolist()[-1] == 1
    assert cols["count_left_output"].tolist()[-1] == 0
    assert cols["truth_activity"].tolist()[-1] == ""

    few = tick_queries.columns(engine, run_id, fields=("t", "lock_right"), last_id=None)
    assert list(few) == ["t", "lock_right"] and few["t"].tolist() == cols["t"].tolist()
    with pytest.raises(ValueError, match="not tick fields: nope"):
        tick_queries.columns(engine, run_id, fields=("t", "nope"))

    back = read_csv(io.StringIO(tick_queries.csv_text(engine, run_id)))
    for name in FIELD_NAMES:
        a, b = back[name].tolist(), cols[name].tolist()
        assert all(x == y or (x != x and y != y) for x, y in zip(a, b, strict=True)), name
    engine.dispose()


def test_fields_read_at_once_equal_the_same_fields_read_one_by_one(
        db_url: str, monkeypatch: pytest.MonkeyPatch) -> None:
    migrate.upgrade(db_url)
    engine = make_engine(db_url)
    rec = TickRecorder(engine)
    run_id = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
    rng = np.random.default_rng(3)
    records = [TickRecord(seq=k, t=k / 100, q_left=float(rng.normal()),
                          post_squat=math.nan if k % 3 else float(rng.random()),
                          controller_ran=k % 2 == 0, lock_left=k % 5 == 0, action=k % 5,
                          truth_activity=("stand", "squat", "")[k % 3], truth_lift=k % 4 - 1,
                          flags=k * 7, torque_right=float(rng.normal()))
               for k in range(50)]
    rec.add(TickBatch.from_records(1, records))
    assert rec.flush() == 50
    with engine.begin() as conn:  # a row with NULL outside the floats (older schema)
        conn.execute(text("INSERT INTO ticks (run_id, seq, t) VALUES (:r, 50, 0.5)"),
                     {"r": run_id})
    alone = TickData({n: tick_queries.columns(engine, run_id, fields=(n,))[n]
                      for n in FIELD_NAMES}).as_dict()
    queries: list[tuple[str, ...]] = []
    real = tick_queries.columns

    def counted(*args: object, **kwargs: object) -> dict[str, np.ndarray]:
        queries.append(tuple(kwargs["fields"]))  # type: ignore[arg-type]
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(tick_queries, "columns", counted)

    @settings(max_examples=40, deadline=None)
    @given(st.lists(st.sampled_from(FIELD_NAMES), unique=True, max_size=16))
    def check(fields: list[str]) -> None:
        queries.clear()
        ticks = tick_queries.run_ticks(engine, run_id, fields)
        asked = ("t", *(n for n in fields if n != "t"))
        assert len(ticks) == 51 and queries == [asked]  # one query for all of them
        got = ticks.as_dict()  # every other field read when needed, on its own
        assert sorted(queries[1:]) == sorted((n,) for n in FIELD_NAMES if n not in asked)
        assert sorted(got) == sorted(alone)
        for name in FIELD_NAMES:
            assert got[name].dtype == alone[name].dtype, name
            np.testing.assert_array_equal(got[name], alone[name], err_msg=name)

    check()
    with pytest.raises(ValueError, match="not tick fields: nope"):
        tick_queries.run_ticks(engine, run_id, ("q_left", "nope"))
    assert len(tick_queries.run_ticks(engine, None, ("q_left",))) == 0
    engine.dispose()
