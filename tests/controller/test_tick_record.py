"""The tick record's flat views agree with the dataclass's own definition of them."""

from __future__ import annotations

import dataclasses

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
