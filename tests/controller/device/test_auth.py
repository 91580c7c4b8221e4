"""Link authentication helpers: the key file, the key's public id, device ids."""

from __future__ import annotations

import hashlib
import hmac
import os
import stat
from pathlib import Path

import pytest

from controller.device.auth import (
    KEY_BYTES,
    KeyFileError,
    key_id,
    load_key,
    load_or_create_key,
    new_session,
    parse_unique_id,
    simulated_unique_id,
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


def test_key_id_names_the_key_without_revealing_it() -> None:
    key = bytes(range(32))
    expected = hmac.new(key, b"exostudy key id", hashlib.sha256).hexdigest()[:16]
    assert key_id(key) == expected and len(expected) == 16
    assert key_id(bytes(32)) != key_id(key)
    assert key.hex()[:16] not in key_id(key)


def test_simulated_unique_id_follows_the_key() -> None:
    key = bytes(range(32))
    expected = hmac.new(key, b"exostudy simulated device", hashlib.sha256).digest()[:16]
    assert simulated_unique_id(key) == expected
    assert simulated_unique_id(bytes(32)) != expected


@pytest.mark.parametrize(("text", "raw"), [
    ("1", "10" + "00" * 15), ("abc", "abc0" + "00" * 14), ("0011", "0011" + "00" * 14),
    ("ff" * 16, "ff" * 16), ("ABCDEF", "abcdef" + "00" * 13)])
def test_device_ids_are_hex_zero_padded_to_16_bytes(text: str, raw: str) -> None:
    assert parse_unique_id(text).hex() == raw


@pytest.mark.parametrize("text", ["", "0" * 33, "xyz", "12 34", "-1"])
def test_bad_device_ids_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="hex digits"):
        parse_unique_id(text)


def test_sessions_are_random_and_never_0() -> None:
    drawn = {new_session() for _ in range(1000)}
    assert len(drawn) == 1000 and 0 not in drawn
    assert all(0 < s < 2**64 for s in drawn)
