"""The export's data dictionary covers every exported column."""

from __future__ import annotations

from backend.analysis.data_dictionary import describe, markdown
from backend.analysis.export import EXPORTED_COLUMNS
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


def test_secrets_are_never_exported() -> None:
    flat = {c for cols in EXPORTED_COLUMNS.values() for c in cols}
    assert not flat & {"password_hash", "token_hash"}
    assert "users" not in EXPORTED_COLUMNS


def test_readme_names_units() -> None:
    text = markdown()
    assert "| height_m | m | body height |" in text
    assert "| torque_left | Nm |" in text
