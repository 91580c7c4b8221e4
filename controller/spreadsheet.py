"""CSV and TSV text that a spreadsheet opens as data, never as a formula.

Exports carry text typed by people (notes, marker labels, LSL marker samples from other
programs). A cell such as `=HYPERLINK(...)` or `@SUM(...)` is run as a formula by
Excel, LibreOffice and Google Sheets when the file is opened, so one participant note
could make an analyst's spreadsheet fetch a URL or run a command (CSV injection). OWASP's
advice, followed here: a *text* cell that starts with `=`, `+`, `-`, `@`, a tab or a
carriage return gets a leading single quote, which every spreadsheet shows as text.
Numbers are not text: `-1.5` stays `-1.5`, and so does a text cell that is just a
number (a spreadsheet reads it as that number, not a formula).

Every CSV and TSV the project writes goes through `writer` (or `table_text`), so a new
export cannot forget it.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Iterable, Sequence
from typing import IO, Any

#: First characters that make a spreadsheet read a cell as a formula (OWASP, "CSV
#: Injection"): the four formula starters, and tab and carriage return, which some
#: spreadsheets strip before looking at the first character.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")

#: A number as Python, numpy or a person writes it (repr of a float included).
_NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf|infinity|nan)",
                     re.IGNORECASE)


def safe_cell(value: Any) -> Any:
    """The cell as it may be written: text a spreadsheet would run as a formula gets a
    leading single quote; everything else (numbers, numeric text, None) is unchanged."""
    if (isinstance(value, str) and value.startswith(FORMULA_STARTS)
            and _NUMBER.fullmatch(value) is None):
        return "'" + value
    return value


class SafeWriter:
    """`csv.writer` whose every cell passes through `safe_cell`.

    CSV: fields are quoted where needed, and a row with a carriage return in a text
    cell is quoted whole (Python's writer quotes only the line terminator `\n`, so a
    lone `\r` would otherwise end the row for a reader). TSV (BIDS' form): never quoted,
    so a tab, carriage return or newline inside a text cell becomes a space."""

    def __init__(self, out: IO[str], delimiter: str = ",") -> None:
        self._tsv = delimiter == "\t"
        if self._tsv:
            self._w = csv.writer(out, delimiter="\t", lineterminator="\n",
                                 quoting=csv.QUOTE_NONE, quotechar=None)
        else:
            self._w = csv.writer(out, delimiter=delimiter, lineterminator="\n")
            self._quoted = csv.writer(out, delimiter=delimiter, lineterminator="\n",
                                      quoting=csv.QUOTE_ALL)

    def writerow(self, row: Iterable[Any]) -> None:
        """Write one row."""
        cells = [safe_cell(v) for v in row]
        if self._tsv:
            self._w.writerow([_one_line(v) if isinstance(v, str) else v for v in cells])
        elif any(isinstance(v, str) and "\r" in v for v in cells):
            self._quoted.writerow(cells)
        else:
            self._w.writerow(cells)

    def writerows(self, rows: Iterable[Iterable[Any]]) -> None:
        """Write many rows."""
        for row in rows:
            self.writerow(row)


def _one_line(text: str) -> str:
    return text.replace("\t", " ").replace("\r", " ").replace("\n", " ")


def writer(out: IO[str], delimiter: str = ",") -> SafeWriter:
    """A CSV (or, with `delimiter="\\t"`, TSV) writer for an export: rows end in `\\n`,
    text cells that would run as formulas are neutralised."""
    return SafeWriter(out, delimiter)


def table_text(header: Sequence[Any] | None, rows: Iterable[Iterable[Any]],
               delimiter: str = ",") -> str:
    """A whole table as CSV/TSV text (no header line if `header` is None)."""
    buf = io.StringIO()
    w = writer(buf, delimiter)
    if header is not None:
        w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()
