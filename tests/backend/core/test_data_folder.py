"""The data is its owner's alone whatever the umask: the data folder 0700, the database
and its WAL, shared-memory and journal files 0600, exports the same; looser modes left
by an older installation are tightened at start and logged; `exostudy doctor` warns
about what others can still read. Every test runs with the usual umask, 022."""

from __future__ import annotations

import logging
import os
import sqlite3
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from backend.cli import main
from backend.core import config
from backend.core.config import Settings
from backend.core.data_folder import prepare_sqlite
from backend.main import create_app
from tests.backend.export_study import make_study


def mode(path: Path) -> int:
    return stat.S_IMODE(os.lstat(path).st_mode)


@pytest.fixture(autouse=True)
def umask_022() -> Iterator[None]:
    """The umask most systems give a login shell (files 0644, folders 0755)."""
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


@pytest.fixture
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A data folder that does not exist yet, as in a first start of a wheel install."""
    folder = tmp_path / "xdg" / "exostudy"
    monkeypatch.setattr(config, "DATA_DIR", folder)
    return folder


def _settings(data: Path, default_sets: tuple[Path, Path]) -> Settings:
    models, utilities = default_sets
    return Settings(  # type: ignore[call-arg]
        database_url=f"sqlite:///{data / 'exostudy.db'}", run_dir=data,
        device_key_file=data / "device.key", start_worker=False, demo=False,
        models_path=models, utilities_dir=utilities, device_kind="sim", _env_file=None)


def test_a_first_start_makes_the_folder_and_the_database_private(
        data: Path, default_sets: tuple[Path, Path]) -> None:
    with TestClient(create_app(_settings(data, default_sets))) as client:
        assert client.get("/api/health").status_code == 200
        db = data / "exostudy.db"
        # While the server runs, SQLite keeps its write-ahead log and shared memory.
        wal, shm = db.with_name("exostudy.db-wal"), db.with_name("exostudy.db-shm")
        assert wal.exists() and shm.exists()
        assert {p.name: oct(mode(p)) for p in (db, wal, shm)} == {
            "exostudy.db": "0o600", "exostudy.db-wal": "0o600", "exostudy.db-shm": "0o600"}
        assert oct(mode(data)) == "0o700"


def test_looser_modes_of_an_older_installation_are_tightened_at_start_and_logged(
        data: Path, default_sets: tuple[Path, Path], caplog: pytest.LogCaptureFixture
) -> None:
    settings = _settings(data, default_sets)
    with TestClient(create_app(settings)):
        pass
    db = data / "exostudy.db"
    pid_log = data / "device-sim-5555.log"
    pid_log.write_text("left by an older version\n")
    reports = data / "replication"
    reports.mkdir()
    for path, loose in ((data, 0o755), (db, 0o644), (pid_log, 0o644), (reports, 0o775)):
        os.chmod(path, loose)
    with caplog.at_level(logging.WARNING, logger="backend.main"), \
            TestClient(create_app(settings)):
        pass
    assert [oct(mode(p)) for p in (data, db, pid_log, reports)] == [
        "0o700", "0o600", "0o600", "0o700"]
    text = caplog.text
    assert "made private" in text
    for line in (f"{data} 755 -> 700", f"{db} 644 -> 600", f"{pid_log} 644 -> 600",
                 f"{reports} 775 -> 700"):
        assert line in text, line


def test_the_rollback_journal_takes_the_private_mode_of_the_database(tmp_path: Path) -> None:
    db = tmp_path / "new" / "journal.db"
    prepare_sqlite(f"sqlite:///{db}")
    assert oct(mode(db)) == "0o600" and oct(mode(db.parent)) == "0o700"
    conn = sqlite3.connect(db, isolation_level=None)
    try:
        conn.execute("PRAGMA journal_mode=DELETE")
        conn.execute("CREATE TABLE t (x)")
        conn.execute("BEGIN")
        conn.execute("INSERT INTO t VALUES (1)")
        journal = db.with_name("journal.db-journal")
        assert journal.exists() and oct(mode(journal)) == "0o600"
        conn.execute("COMMIT")
    finally:
        conn.close()


def test_doctor_warns_about_a_data_folder_others_can_read(
        data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)  # no .env of the clone
    for name in ("DATABASE_URL", "RUN_DIR", "DEVICE_KEY_FILE"):
        monkeypatch.delenv(f"EXOSTUDY_{name}", raising=False)
    monkeypatch.setenv("EXOSTUDY_DATABASE_URL", f"sqlite:///{data / 'exostudy.db'}")
    monkeypatch.setenv("EXOSTUDY_RUN_DIR", str(data))
    monkeypatch.setenv("EXOSTUDY_DEVICE_KEY_FILE", str(data / "device.key"))
    data.mkdir(parents=True)
    os.chmod(data, 0o755)
    (data / "exostudy.db").write_bytes(b"")
    os.chmod(data / "exostudy.db", 0o644)
    assert main(["doctor"]) == 1
    out = capsys.readouterr().out
    assert f"warning: {data}: folder readable or writable by others (mode 755)" in out
    assert f"warning: {data / 'exostudy.db'}: file readable or writable by others " \
           "(mode 644)" in out
    os.chmod(data, 0o700)
    os.chmod(data / "exostudy.db", 0o600)
    assert main(["doctor"]) == 0
    assert capsys.readouterr().out.startswith("ok: ")


def test_doctor_walks_the_whole_data_folder_without_following_links(
        data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Folders and files deep inside the data folder count too (models/ 777 and a model
    file 666 once went unreported); a symbolic link is not followed out of the tree."""
    monkeypatch.chdir(tmp_path)
    for name in ("DATABASE_URL", "RUN_DIR", "DEVICE_KEY_FILE"):
        monkeypatch.delenv(f"EXOSTUDY_{name}", raising=False)
    monkeypatch.setenv("EXOSTUDY_DATABASE_URL", f"sqlite:///{data / 'exostudy.db'}")
    monkeypatch.setenv("EXOSTUDY_RUN_DIR", str(data))
    monkeypatch.setenv("EXOSTUDY_DEVICE_KEY_FILE", str(data / "device.key"))
    prepare_sqlite(f"sqlite:///{data / 'exostudy.db'}")
    models = data / "models"
    deep = data / "runs" / "r1" / "figures"
    deep.mkdir(parents=True)  # 0755 each under umask 022
    models.mkdir()
    (models / "sim-default.json").write_text("{}")  # 0644
    (deep / "fig.svg").write_text("<svg/>")
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "open.txt").write_text("x")
    (data / "link").symlink_to(outside)
    for p in (data / "runs", data / "runs" / "r1", deep):
        os.chmod(p, 0o700)
    os.chmod(models, 0o777)
    os.chmod(models / "sim-default.json", 0o666)
    assert main(["doctor"]) == 1
    out = capsys.readouterr().out
    assert f"warning: {models}: folder readable or writable by others (mode 777)" in out
    assert f"warning: {models / 'sim-default.json'}: file readable or writable by others " \
           "(mode 666)" in out
    assert f"warning: {deep / 'fig.svg'}: file readable or writable by others (mode 644)" in out
    assert str(outside) not in out
    assert "3 path(s) open to others" in out
    for p in (models, models / "sim-default.json", deep / "fig.svg"):
        os.chmod(p, 0o700 if p.is_dir() else 0o600)
    assert main(["doctor"]) == 0
    assert capsys.readouterr().out.startswith("ok: ")


def test_doctor_names_the_first_paths_and_counts_the_rest(
        data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from backend.core import data_folder

    monkeypatch.setattr(data_folder, "MAX_LISTED", 3)
    monkeypatch.setattr(data_folder, "MAX_WALKED", 8)
    data.mkdir(parents=True, mode=0o700)
    os.chmod(data, 0o700)
    for i in range(10):
        (data / f"f{i}").write_text("x")  # 0644
    found = data_folder.exposures(Settings(  # type: ignore[call-arg]
        database_url=f"sqlite:///{data / 'exostudy.db'}", run_dir=data,
        device_key_file=data / "device.key", _env_file=None))
    assert (len(found.listed), found.count, found.walk_stopped) == (3, 8, True)
    lines = found.lines()
    assert lines[3].startswith("... and 5 more paths open to others (8 in all")
    assert lines[4].startswith("stopped looking after 8 entries")


def test_exports_on_disk_are_private(client: TestClient, db_url: str, tmp_path: Path) -> None:
    make_study(client, db_url)
    bids, results = tmp_path / "bids", tmp_path / "results"
    assert main(["export", "--study", "1", "--bids", str(bids), "--db", db_url]) == 0
    assert main(["results", "--study", "1", "--out", str(results), "--db", db_url,
                 "--no-timelines"]) == 0
    for root in (bids, results):
        written = [root, *root.rglob("*")]
        assert len(written) > 5
        loose = {str(p.relative_to(tmp_path)): oct(mode(p)) for p in written
                 if mode(p) & 0o077}
        assert loose == {}
