"""`exostudy replicate` on a tiny run: the report, its figures and the seed reuse."""

from __future__ import annotations

import json
import os
import re
import stat
import subprocess
from pathlib import Path

import pytest

from backend.analysis import replication_report, replication_run
from backend.analysis.replication_config import Replication, ReplicationConfig
from backend.analysis.replication_run import run, run_study_seed
from backend.cli import main
from controller.evaluation.paper_claims import CLAIMS


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("replication")
    run(ReplicationConfig(out=out, seeds=2, engine="cohort", participants=2, eumc=1,
                          data_participants=2, offset_participants=6, stair_participants=2),
        log=lambda _m: None)
    return out


def test_report_is_self_contained_and_judges_every_claim(tiny: Path) -> None:
    page = (tiny / "report.html").read_text()
    # No resource from the network: every image is a data URI.
    assert not re.search(r"""src=['"]https?:""", page)
    assert page.count("src='data:image/png;base64,") >= 9
    doc = json.loads((tiny / "replication.json").read_text())
    assert [c["key"] for c in doc["claims"]] == [c.key for c in CLAIMS]
    assert {c["verdict"] for c in doc["claims"]} <= {"reproduced", "equivalent", "differs",
                                                     "inconclusive", "not simulated"}
    by = {c["key"]: c for c in doc["claims"]}
    assert by["questionnaires"]["verdict"] == "not simulated"
    assert by["chi_square"]["verdict"] == "reproduced"
    assert len(doc["seeds"]) == 2 and by["umc.correct.SQ"]["interval"]["n"] == 2
    for name in ("peak_torques", "controller_output", "motion_models", "utilities",
                 "actuator", "chi_square", "offsets_both", "stairs"):
        assert (tiny / "figures" / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert b"<svg" in (tiny / "figures" / f"{name}.svg").read_bytes()[:2000]
    md = (tiny / "replication.md").read_text()
    assert md.count("\n| ") == len(CLAIMS) + 1
    # The muscle-activity section (an EMG cohort, controller.evaluation.muscle_report).
    assert "Reduction of the mean normalised envelope against no exoskeleton" in page
    assert (tiny / "figures" / "muscle_envelope.png").read_bytes()[:4] == b"\x89PNG"


def test_the_default_seed_count_is_the_measured_one() -> None:
    from backend.cli import build_parser
    from backend.schemas.replication import ReplicationIn
    from controller.evaluation.paper_claims import DEFAULT_SEEDS

    assert ReplicationConfig(out=Path("x")).seeds == DEFAULT_SEEDS
    assert ReplicationIn.model_fields["seeds"].default == DEFAULT_SEEDS
    assert build_parser().parse_args(["replicate", "--out", "x"]).seeds is None


def test_the_cohort_engine_is_the_default_and_help_says_so() -> None:
    from backend.cli import build_parser

    assert ReplicationConfig(out=Path("x")).engine == "cohort"
    parser = build_parser()
    assert parser.parse_args(["replicate", "--out", "x"]).engine == "cohort"
    assert parser.parse_args(["replicate", "--out", "x", "--engine", "study"]).engine == "study"
    sub = next(a for a in parser._actions if a.dest == "command").choices["replicate"]
    text = " ".join(sub.format_help().split())
    assert "cohort (the default)" in text and "about 100 minutes" in text


def test_the_report_template_escapes_what_it_shows(tmp_path: Path) -> None:
    """Rendered by the Jinja2 template with autoescape: a note with markup stays text."""
    rep = Replication(ReplicationConfig(out=tmp_path, seeds=2))
    rep.notes = ["<script>alert(1)</script> & more"]
    rep.sections = {"muscle_activity": "| a | b |\n| --- | --- |"}
    page = replication_report.report_html(rep)
    assert "<script>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; more" in page
    assert "<h3>Virtual, first seed: muscle activity</h3>" in page
    assert page.count("<table>") == 3  # the claims and the paper's two tables, no more


def test_offsets_regression_is_ordinary_least_squares(tiny: Path) -> None:

    doc = json.loads((tiny / "replication.json").read_text())
    both = doc["offsets"]["both"]
    assert both["n"] == 6 and both["low"] < both["slope"] < both["high"]


def test_a_finished_seed_is_reused_and_an_unfinished_one_refused(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = ReplicationConfig(out=tmp_path, seeds=2)
    done = replication_run.study_seed_folder(tmp_path, 1)
    done.mkdir(parents=True)
    (done / "study.db").write_bytes(b"")
    (done / "summary.json").write_text("{}")

    def no_run(*_a: object, **_k: object) -> int:
        raise AssertionError("a finished seed must not run again")

    monkeypatch.setattr(subprocess, "call", no_run)
    assert run_study_seed(cfg, 1, lambda _m: None) == done / "study.db"
    replication_run.study_seed_folder(tmp_path, 2).mkdir(parents=True)
    with pytest.raises(ValueError, match="unfinished virtual study"):
        run_study_seed(cfg, 2, lambda _m: None)


def test_bad_arguments_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replicate", "--out", str(tmp_path), "--seeds", "1"]) == 2
    assert "seeds" in capsys.readouterr().err
    assert main(["replicate", "--out", str(tmp_path), "--from-db",
                 str(tmp_path / "missing.db")]) == 2
    assert "--from-db" in capsys.readouterr().err


def test_the_report_and_its_figures_are_private_whatever_the_umask(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Inside the 0700 run folder the report was written 0644 and figures/ 0755."""
    out = tmp_path / "run"
    old = os.umask(0o022)
    try:
        (out / "figures").mkdir(parents=True)  # left 0755 by an earlier run
        os.chmod(out, 0o700)
        rep = Replication(ReplicationConfig(out=out, seeds=2))
        rep.figures = {"peak_torques": (b"\x89PNG", b"<svg/>")}
        written = replication_report.write(rep)
        modes = {p.relative_to(out).as_posix(): oct(stat.S_IMODE(p.stat().st_mode))
                 for p in [out / "figures", *written]}
        assert modes == {
            "figures": "0o700", "figures/peak_torques.png": "0o600",
            "figures/peak_torques.svg": "0o600", "replication.json": "0o600",
            "replication.md": "0o600", "report.html": "0o600"}
        assert (out / "figures" / "peak_torques.svg").read_bytes() == b"<svg/>"
        # A seed's log is private, and the virtual study it runs writes with umask 077.
        seen: dict[str, object] = {}

        def failing_study(cmd: list[str], **kwargs: object) -> int:
            seen.update(kwargs)
            return 1

        monkeypatch.setattr(subprocess, "call", failing_study)
        with pytest.raises(RuntimeError, match="the virtual study failed"):
            run_study_seed(ReplicationConfig(out=out, seeds=2), 1, lambda _m: None)
    finally:
        os.umask(old)
    assert seen["umask"] == 0o077
    log = out / "seed-1.log"
    studies = replication_run.study_seed_folder(out, 1).parent
    assert [oct(stat.S_IMODE(p.stat().st_mode)) for p in (log, studies)] == ["0o600", "0o700"]
