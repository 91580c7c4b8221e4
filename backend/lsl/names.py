"""Names and source ids of LSL streams, as the experimenter types them, and the resolver
query built from them.

liblsl finds streams with an XPath predicate (`name='...'`). A quote in the text ends
the string early: liblsl then rejects the query and returns at once with nothing found,
so a reader that retries spins on a core (issue 23: `'` in a subscribed name used 92 %
of a core, and again after every restart). Only text that cannot change the query's
meaning is accepted, and the query is built in one place, after the check.
"""

from __future__ import annotations

import re
from typing import Any, Literal

#: Letters, digits, space and `. _ - : @ # + / ( )`, starting with a letter or digit, at
#: most 200 characters (the column's size). Enough for the names LabRecorder, OpenBCI
#: and vendors' apps publish (`openvibeMarkers`, `Tobii:gaze@lab-pc`); no quote,
#: bracket, `=` or backslash, which are XPath syntax.
LSL_TEXT_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9 ._:@#+/()-]{0,199}$"

_ALLOWED = re.compile(LSL_TEXT_PATTERN)

Property = Literal["name", "source_id"]


def problem(text: str) -> str | None:
    """What is wrong with a stream name or source id, or None if it may be used."""
    if _ALLOWED.fullmatch(text) is None:
        return (f"{text[:50]!r} is not a name the LSL resolver can search for: use 1-200 "
                "letters, digits, spaces or . _ - : @ # + / ( ), starting with a letter "
                "or digit")
    return None


def predicate(prop: Property, value: str) -> str:
    """The resolver query for streams whose `prop` equals `value`; ValueError for a
    value `problem` refuses (it would change the query)."""
    why = problem(value)
    if why is not None:
        raise ValueError(why)
    return f"{prop}='{value}'"


def lsl_errors(pylsl: Any) -> tuple[type[BaseException], type[BaseException]]:
    """liblsl's "stream lost" and "timed out" exceptions: `pylsl.LostError` up to 1.16,
    `pylsl.util` from 1.17 on (whose TimeoutError is not the built-in one)."""
    util: Any = getattr(pylsl, "util", None) or getattr(pylsl, "pylsl", None)
    lost: type[BaseException] = getattr(pylsl, "LostError", None) or util.LostError
    timeout: type[BaseException] = getattr(util, "TimeoutError", TimeoutError)
    return lost, timeout
