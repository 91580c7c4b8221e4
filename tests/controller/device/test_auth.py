"""Link authentication helpers: the key file, the replay window, peer sessions."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.device.auth import (
    KEY_BYTES,
    WINDOW,
    KeyFileError,
    PeerSessions,
    ReplayWindow,
    load_key,
    load_or_create_key,
    new_session,
)


def test_key_file_is_created_private_and_read_back(tmp_path: Path) -> None:
    path = tmp_path / "var" / "device.key"
    key = load_or_create_key(path)
    assert len(key) == KEY_BYTES
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert path.read_text() == key.hex() + "\n"
    assert load_or_create_key(path) == key  # the second start keeps it
    assert [p.name for p in path.parent.iterdir()] == ["device.key"]  # no temporary left


def test_key_file_readable_by_others_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "device.key"
    load_or_create_key(path)
    os.chmod(path, 0o644)
    with pytest.raises(KeyFileError, match="readable by others"):
        load_key(path)


@pytest.mark.parametrize(("text", "problem"), [("zz", "hexadecimal"), ("00" * 16, "32 bytes")])
def test_malformed_key_files_are_refused(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "device.key"
    path.write_text(text)
    os.chmod(path, 0o600)
    with pytest.raises(KeyFileError, match=problem):
        load_key(path)
    with pytest.raises(KeyFileError, match="no device key"):
        load_key(tmp_path / "missing.key")


@settings(max_examples=300)
@given(st.integers(0, 2**32 - 1), st.lists(st.integers(-100, 100), max_size=200))
def test_window_accepts_exactly_the_new_numbers_inside_it(start: int, steps: list[int]) -> None:
    """Oracle: the set of numbers seen and the highest one, in unbounded integers."""
    w = ReplayWindow()
    seen: set[int] = set()
    top: int | None = None
    n = 0
    for step in [0, *steps]:
        n += step
        expected = n not in seen and (top is None or n > top - WINDOW)
        assert w.accept((start + n) % 2**32) is expected
        if expected:
            seen.add(n)
            top = n if top is None else max(top, n)


def test_sessions_start_once_and_retired_ones_never_return() -> None:
    peer = PeerSessions()
    a, b = new_session(), new_session()
    assert (peer.check(a, 5), peer.check(a, 6), peer.check(a, 6)) == ("new", "ok", "replay")
    assert peer.check(b, 0) == "new"  # the peer restarted
    assert peer.check(a, 7) == "replay"  # its earlier session, even with a new number
    assert peer.check(0, 1) == "replay"  # 0 is never a session
    assert peer.check(new_session(), 1, may_start=False) == "replay"
    assert peer.current == b
