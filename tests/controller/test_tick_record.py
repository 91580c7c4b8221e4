"""The tick record's flat views agree with the dataclass's own definition of them."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from controller.tick_record import TickRecord

_TYPES = TickRecord.field_types()
_VALUE = {int: st.integers(-2**40, 2**40), float: st.floats(allow_nan=True),
          bool: st.booleans(), str: st.text(max_size=12)}


@given(st.fixed_dictionaries({n: _VALUE[t] for n, t in _TYPES.items()}))
def test_as_tuple_and_as_dict_match_dataclasses(values: dict[str, object]) -> None:
    r = TickRecord(**values)  # type: ignore[arg-type]
    expected = dataclasses.astuple(r)
    got = r.as_tuple()
    assert len(got) == len(expected) == len(TickRecord.field_names())
    # NaN != NaN: compare by identity-or-equality, value by value.
    assert all(a is b or a == b for a, b in zip(got, expected, strict=True))
    assert list(r.as_dict()) == list(TickRecord.field_names())
    assert all(r.as_dict()[k] is v or r.as_dict()[k] == v
               for k, v in zip(TickRecord.field_names(), expected, strict=True))


#: The record as the dataclass builds it (its generated `__init__`): the oracle of the
#: slot-setting constructor `controller.tick_record` installs.
_Oracle = dataclasses.make_dataclass(
    "TickRecord",
    [(f.name, f.type, f.default if f.default is not dataclasses.MISSING else dataclasses.field())
     for f in dataclasses.fields(TickRecord)],
    frozen=True, slots=True,
)


def _same(a: tuple[object, ...], b: tuple[object, ...]) -> bool:
    return len(a) == len(b) and all(x is y or x == y for x, y in zip(a, b, strict=True))


@given(st.fixed_dictionaries({n: _VALUE[t] for n, t in _TYPES.items()}), st.integers(0, 55),
       st.booleans())
def test_construction_stores_what_the_dataclass_init_stores(
    values: dict[str, Any], given_n: int, by_keyword: bool
) -> None:
    names = TickRecord.field_names()
    chosen = {n: values[n] for n in names[:max(2, given_n)]}  # seq and t are required
    if by_keyword:
        got, want = TickRecord(**chosen), _Oracle(**chosen)
    else:
        got, want = TickRecord(*chosen.values()), _Oracle(*chosen.values())
    assert _same(got.as_tuple(), dataclasses.astuple(want))
    assert _same(tuple(getattr(got, n) for n in names), dataclasses.astuple(want))
    # The copy with changes is `dataclasses.replace`'s.
    change = {n: values[n] for n in names[given_n % len(names):][:3]}
    assert _same(got.with_(**change).as_tuple(), dataclasses.replace(got, **change).as_tuple())


def test_construction_keeps_the_dataclass_signature_and_refusals() -> None:
    import inspect

    got, want = inspect.signature(TickRecord), inspect.signature(_Oracle)
    assert [(p.name, p.kind, p.annotation) for p in got.parameters.values()] == [
        (p.name, p.kind, p.annotation) for p in want.parameters.values()]
    # The defaults are the very objects (NaN is the `math.nan` every record shares).
    assert all(a.default is b.default for a, b in zip(
        got.parameters.values(), want.parameters.values(), strict=True))
    r = TickRecord(1, 0.5)
    assert r == TickRecord(seq=1, t=0.5) and hash(r) == hash(TickRecord(1, 0.5))
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.flags = 3  # type: ignore[misc]
    with pytest.raises(TypeError, match="'t'"):
        TickRecord(1)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="bogus"):
        TickRecord(1, 0.5, bogus=2)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="multiple values"):
        TickRecord(1, 0.5, seq=2)  # type: ignore[misc]
    with pytest.raises(TypeError, match="bogus"):
        r.with_(bogus=2)
    assert r.with_().as_tuple() == r.as_tuple() and r.with_() is not r
