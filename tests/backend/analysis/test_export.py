"""The export's data dictionary covers every exported column."""

from __future__ import annotations

from sqlalchemy import Column, Integer, MetaData

from backend.analysis.data_dictionary import (
    COLUMNS,
    EXPORTED_TABLES,
    SEGMENT_TABLES,
    describe,
    markdown,
    undocumented,
)
from backend.analysis.export import EXPORTED_COLUMNS
from backend.db.tables import Base
from controller.tick_record import TickRecord


def test_every_exported_column_has_a_unit_and_a_meaning() -> None:
    missing = []
    for table, cols in EXPORTED_COLUMNS.items():
        for c in cols:
            try:
                _unit, meaning = describe(table, c)
            except KeyError:
                missing.append(f"{table}.{c}")
                continue
            assert meaning
    assert not missing, f"undocumented exported columns: {missing}"
    for f in TickRecord.field_names():
        assert describe("ticks", f)[1]


def test_a_column_added_to_a_model_without_a_description_is_named() -> None:
    assert undocumented() == []
    metadata = MetaData()
    for table in Base.metadata.sorted_tables:
        table.to_metadata(metadata)
    metadata.tables["participants"].append_column(Column("shoe_size", Integer))
    metadata.tables["trial_segments"].append_column(Column("confidence", Integer))
    assert undocumented(metadata) == ["participants.shoe_size", "trial_segments.confidence"]


def test_every_description_is_of_an_exported_column() -> None:
    """No description outlives its column: `table.column` names a column of the model,
    `segments.column` one of both segment tables, `*.column` one of some table."""
    stale = []
    for key in COLUMNS:
        table, column = key.split(".", 1)
        where = (EXPORTED_TABLES if table == "*" else sorted(SEGMENT_TABLES)
                 if table == "segments" else (table,))
        have = [column in EXPORTED_COLUMNS.get(t, ()) for t in where]
        if not (any(have) if table == "*" else have and all(have)):
            stale.append(key)
    assert stale == []


def test_secrets_are_never_exported() -> None:
    flat = {c for cols in EXPORTED_COLUMNS.values() for c in cols}
    assert not flat & {"password_hash", "token_hash"}
    assert "users" not in EXPORTED_COLUMNS


def test_readme_names_units() -> None:
    text = markdown()
    assert "| height_m | m | body height |" in text
    assert "| torque_left | Nm |" in text
