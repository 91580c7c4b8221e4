"""`exostudy results`: the same tables and figures as the API, from a database file, and
one-line errors for a wrong file or study."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from backend.cli import main
from backend.core.config import Settings
from tests.backend.analysis.test_results import _setup


def test_the_command_writes_what_the_api_serves(client: TestClient, settings: Settings,
                                                tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    ids = _setup(client, settings)
    out = tmp_path / "results"
    assert main(["results", "--db", settings.database_url, "--study", str(ids["study"]),
                 "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    for table in ("performance", "false_positives", "questionnaires", "lifts"):
        api = client.get(f"/api/studies/{ids['study']}/results/{table}.csv").text
        assert (out / f"{table}.csv").read_text() == api
        api_md = client.get(f"/api/studies/{ids['study']}/results/{table}.md").text
        assert (out / f"{table}.md").read_text() == api_md
    assert (out / "peak_torques.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in (out / "onset_to_lock.svg").read_bytes()[:2000]
    assert (out / f"timeline-trial-{ids['umc']}.png").stat().st_size > 10_000
    assert '"trial_id"' in (out / "results.json").read_text()


def test_a_missing_file_or_study_is_one_line_and_exit_2(
        client: TestClient, settings: Settings, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    ids = _setup(client, settings)
    missing = tmp_path / "nope.db"
    assert main(["results", "--db", str(missing), "--study", "1", "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "no database file" in err and str(missing) in err
    assert main(["results", "--db", settings.database_url, "--study", "999",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "no study 999" in err and str(ids["study"]) in err
    assert not (tmp_path / "o").exists()
