"""The BIDS export of a virtual study passes the schema-based BIDS validator with no
error and no warning, for the owner (controllers named) and blinded; subjects share
session names; a study without data is refused with the reason (CLI exit 2, REST 409)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from backend.analysis.virtual_study import DATASET_INFO, VirtualStudyConfig, run
from backend.cli import main
from tests.backend.lab.bids_validator import issues


@pytest.fixture(scope="module")
def virtual_study_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The smallest virtual study that still has two evaluated subjects (each with UMC
    and PEC trials of one squat sequence) and two data-collection subjects."""
    out = tmp_path_factory.mktemp("virtual")
    cfg = VirtualStudyConfig(out=out, participants=2, data_participants=2, eumc=0, seed=5,
                             rates=("paper-rates",), margin_s=1.0, model_evaluation=False,
                             eval_script="squat-sequence")
    run(cfg, log=lambda _m: None)
    return out / "study.db"


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("blind", [False, True], ids=["owner", "blinded"])
def test_the_virtual_studys_bids_export_has_no_error_and_no_warning(
        virtual_study_db: Path, tmp_path: Path, blind: bool) -> None:
    out = tmp_path / "bids"
    assert main(["export", "--study", "1", "--bids", str(out), "--db", str(virtual_study_db),
                 *(["--blind"] if blind else [])]) == 0
    assert issues(out) == []

    description = json.loads((out / "dataset_description.json").read_text())
    assert description["Authors"] == DATASET_INFO["authors"]
    assert description["License"] == DATASET_INFO["license"]
    # One name per visit, the same for every subject.
    sessions = {(p.parent.name, p.name) for p in out.glob("sub-*/ses-*")}
    assert sessions == {("sub-P01", "ses-evaluation1"), ("sub-P02", "ses-evaluation1")}
    motion = sorted(p.name for p in out.glob("sub-*/ses-*/motion/*_motion.tsv"))
    assert len(motion) == 4
    named = {"umc", "pec"} if not blind else {"A", "B"}
    assert {n.split("_acq-")[1].split("_")[0] for n in motion} == named
    # Every column of every table is described in its sidecar.
    for tsv in out.rglob("*.tsv"):
        if tsv.name.endswith(("_motion.tsv", "_channels.tsv")):
            continue  # no header / BIDS' own columns
        sidecar = json.loads(tsv.with_suffix(".json").read_text())
        header = tsv.read_text().splitlines()[0].split("\t")
        assert set(header) - {"HED"} <= set(sidecar), tsv.name


def test_a_study_without_data_is_refused_with_the_reason(
        client: TestClient, db_url: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert client.post("/api/studies", json={"name": "empty"}).status_code == 201
    assert client.post("/api/studies/1/participants", json={"code": "P01"}).status_code == 201
    r = client.get("/api/studies/1/export.bids.zip")
    assert r.status_code == 409, r.text
    assert "no trial with recorded ticks" in r.json()["detail"]
    out = tmp_path / "bids"
    assert main(["export", "--study", "1", "--bids", str(out), "--db", db_url]) == 2
    err = capsys.readouterr().err
    assert "no trial with recorded ticks" in err and "run a trial first" in err
    assert not out.exists() or not any(out.iterdir())
