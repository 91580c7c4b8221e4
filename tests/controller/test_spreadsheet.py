"""CSV/TSV cells a spreadsheet would run as formulas are neutralised; numbers are not.

The oracle is the standard library's CSV reader: what it reads back is what a
spreadsheet gets as the cell's text."""

from __future__ import annotations

import csv
import io

import pytest
from hypothesis import given
from hypothesis import strategies as st

from controller.spreadsheet import FORMULA_STARTS, safe_cell, table_text


def _read(text: str, delimiter: str = ",") -> list[list[str]]:
    return list(csv.reader(io.StringIO(text), delimiter=delimiter))


@pytest.mark.parametrize("cell", ["=1+1", "=HYPERLINK(\"http://x\",\"y\")", "+cmd|' /C calc'!A0",
                                  "-2+3", "@SUM(A1:A2)", "\t=1", "\r=1", "-", "+", "=",
                                  "-cmd", "-1+1", "--1"])
def test_formula_text_gets_a_leading_quote(cell: str) -> None:
    [[back]] = _read(table_text(None, [[cell]]))
    assert back == "'" + cell
    # TSV is never quoted (BIDS): a tab or line break inside a cell becomes a space.
    [[back]] = _read(table_text(None, [[cell]], "\t"), "\t")
    assert back == "'" + cell.replace("\t", " ").replace("\r", " ")


@pytest.mark.parametrize("cell", [-1.5, -1, 0, 2.5e-9, "-1.5", "+3", "-2e-05", "-inf", "1e3",
                                  "hello", "a=b", " =1", "", None, "n/a", "'=already"])
def test_numbers_and_harmless_text_are_unchanged(cell: object) -> None:
    [[back]] = _read(table_text(None, [[cell]]))
    assert back == ("" if cell is None else str(cell))


@given(st.floats(allow_nan=False, allow_infinity=False) | st.integers())
def test_every_number_stays_a_number(x: float) -> None:
    assert safe_cell(x) == x
    assert safe_cell(repr(x)) == repr(x)  # its text form, as the exports write floats
    [[back]] = _read(table_text(None, [[x]]))
    # An integer beyond 2**53 has no exact float: read it back as the integer it is.
    assert (int(back) if isinstance(x, int) else float(back)) == x


@given(st.sampled_from(FORMULA_STARTS), st.text())
def test_any_text_starting_like_a_formula_is_neutralised_unless_a_number(
        start: str, rest: str) -> None:
    cell = start + rest
    out = safe_cell(cell)
    try:
        float(cell)
        numeric = cell.strip() == cell and "_" not in cell
    except ValueError:
        numeric = False
    if numeric:
        assert out in (cell, "'" + cell)  # a number reads as a number either way
    else:
        assert out == "'" + cell


def test_line_breaks_and_quotes_keep_one_row() -> None:
    rows = [["a\rb", 'say "hi"', 1.5], ["x\ny", "=1", -2]]
    assert _read(table_text(["n", "t", "v"], rows)) == [
        ["n", "t", "v"], ["a\rb", 'say "hi"', "1.5"], ["x\ny", "'=1", "-2"]]
    tsv = table_text(["n", "t", "v"], rows, "\t")
    assert tsv.splitlines() == ["n\tt\tv", 'a b\tsay "hi"\t1.5', "x y\t'=1\t-2"]


def test_the_header_is_checked_too() -> None:
    assert _read(table_text(["=x", "y"], [[1, 2]])) == [["'=x", "y"], ["1", "2"]]
