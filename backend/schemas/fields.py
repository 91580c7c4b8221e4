"""Field types the API schemas share: text the database can store on any backend,
pseudonymous codes, blinded labels, and times that always carry their time zone."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

from pydantic import AfterValidator, Field

#: The largest id: ids are bounded to 32-bit integers, so an id beyond what any database
#: column holds is a 404 or 422, never a driver overflow (a 500).
MAX_ID = 2_147_483_647


def _storable(v: str) -> str:
    # PostgreSQL refuses NUL in text and no UTF-8 codec takes lone surrogates: refuse
    # them at the edge (422) instead of failing in the database (500).
    if "\x00" in v:
        raise ValueError("must not contain NUL characters")
    if any("\ud800" <= ch <= "\udfff" for ch in v):
        raise ValueError("must not contain unpaired surrogates")
    return v


def _utc(v: datetime) -> datetime:
    # SQLite returns naive datetimes for timezone-aware columns; they were stored as UTC.
    return v.replace(tzinfo=UTC) if v.tzinfo is None else v.astimezone(UTC)


def _strip_nonempty(v: str) -> str:
    if not v.strip():
        raise ValueError("must not be blank")
    return v.strip()


PlainText = Annotated[str, Field(max_length=4000), AfterValidator(_storable)]
"""Free text (notes, descriptions)."""

Name = Annotated[str, Field(min_length=1, max_length=200), AfterValidator(_storable),
                 AfterValidator(_strip_nonempty)]
"""A human-readable name (a study's)."""

Code = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$",
                            examples=["P01"])]
"""A participant's pseudonymous code: letters, digits, '_' and '-' only, so a name with
spaces cannot slip in by habit."""

Label = Annotated[str, Field(pattern=r"^[A-Z][A-Za-z0-9]{0,15}$", examples=["A"])]
"""A blinded condition label as the participant sees it ("A", "B")."""

UtcDatetime = Annotated[datetime, AfterValidator(_utc)]
"""A time in UTC, time zone included."""


#: The shortest timed run (`duration_s` of a trial, a recording, a long-use block): one
#: 10 ms sample. The worker counts whole samples, so anything shorter would time nothing.
MIN_TIMED_S = 0.01
