"""`exostudy replicate` on a tiny run: the report, its figures and the seed reuse."""

from __future__ import annotations

import argparse
import json
import os
import re
import stat
import subprocess
from pathlib import Path
from typing import Any

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
                          data_participants=2, offset_participants=6, stair_participants=2,
                          personalisation_participants=3),
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
    md = (tiny / "replication.md").read_text().split("\n## ")[0]
    assert md.count("\n| ") == len(CLAIMS) + 1
    # The muscle-activity section (an EMG cohort, controller.evaluation.muscle_report).
    assert "Reduction of the mean normalised envelope against no exoskeleton" in page
    # ... shown as tables, not preformatted Markdown.
    assert "<pre>" not in page and "<th>channel</th>" in page


def _mean_change(rows: list[dict[str, Any]], key: str, cond: str, ref: str, metric: str,
                 **match: object) -> float:
    """Mean per-participant change (cond minus ref) of `metric` in the run's JSON."""
    by: dict[tuple[object, object], dict[str, float]] = {}
    for r in rows:
        if all(r[k] == v for k, v in match.items()):
            by.setdefault((r["seed"], r["participant"]), {})[r[key]] = r[metric]
    d = [v[cond] - v[ref] for v in by.values() if v[cond] is not None and v[ref] is not None]
    assert len(d) == 3
    return sum(d) / len(d)


def test_the_personalisation_section_shows_the_runs_changes(tiny: Path) -> None:
    from controller.evaluation.personalisation import map_condition, with_priors

    doc = json.loads((tiny / "replication.json").read_text())["personalisation"]
    assert doc["participants"] == 3 and doc["config"]["seeds"] == [1]
    md = (tiny / "replication.md").read_text()
    page = (tiny / "report.html").read_text()
    assert "## Personalisation (beyond the paper)" in md
    assert "<h2>Personalisation (beyond the paper)</h2>" in page
    assert "![" in md and "figures/personalisation_curve.png" in md
    assert (tiny / "figures" / "personalisation_curve.png").read_bytes()[:4] == b"\x89PNG"
    assert "alt=\"personalisation_curve\"" in page
    lab, day = doc["per_participant"]["lab"], doc["per_participant"]["day"]
    for ctl, label in (("umc", "UMC"), ("eumc", "E-UMC")):
        for cond, text in ((map_condition(10), "MAP-adapted, 10 demos/motion"),
                           (map_condition(3), "MAP-adapted, 3 demos/motion"),
                           (with_priors("population"), "population models + learned "
                            "priors")):
            want = _mean_change(lab, "condition", cond, "population", "correct_pct",
                                controller=ctl)
            row = f"| {label} | {text} | "
            line = next(x for x in md.splitlines() if x.startswith(row))
            shown = line.split(" | ")[4].split(" [")[0]
            assert shown == f"{want:.2f}", (line, want)
            # The same row in the HTML, as table cells.
            assert f"<td>{label}</td><td>{text}</td>" in page
            assert f"<td>{shown} [" in page
    for metric, text in (("fp_stairs", "UMC false positive lock signals in stair bouts, "
                          "per day"), ("correct", "correct lift decisions per day")):
        want = _mean_change(day, "priors", "learned", "equal", metric)
        line = next(x for x in md.splitlines() if x.startswith(f"| {text} |"))
        assert line.split(" | ")[3].split(" [")[0] == f"{want:.2f}", (line, want)
        assert f"<td>{text}</td>" in page
    assert (tiny / "figures" / "muscle_envelope.png").read_bytes()[:4] == b"\x89PNG"


def _replicate_parser(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    choices = next(a for a in parser._actions if a.dest == "command").choices
    assert isinstance(choices, dict)
    sub = choices["replicate"]
    assert isinstance(sub, argparse.ArgumentParser)
    return sub


def test_the_personalisation_size_is_bounded_and_its_default_documented() -> None:
    from backend.analysis.replication_config import DEFAULT_PERSONALISATION
    from backend.cli import build_parser

    assert ReplicationConfig(out=Path("x")).personalisation_participants == \
        DEFAULT_PERSONALISATION
    assert ReplicationConfig(out=Path("x"), personalisation_participants=0) is not None
    with pytest.raises(ValueError, match="personalisation_participants"):
        ReplicationConfig(out=Path("x"), personalisation_participants=2)
    parser = build_parser()
    sub = _replicate_parser(parser)
    text = " ".join(sub.format_help().split())
    assert f"default {DEFAULT_PERSONALISATION}: DEFAULT_PERSONALISATION" in text
    assert "about 2.5 min measured here; 0 leaves the section out" in text


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
    sub = _replicate_parser(parser)
    text = " ".join(sub.format_help().split())
    assert "cohort (the default)" in text and "about 100 minutes" in text


def test_the_report_template_escapes_what_it_shows(tmp_path: Path) -> None:
    """Rendered by the Jinja2 template with autoescape: a note or a section's text with
    markup stays text, and a section's Markdown table becomes a table."""
    rep = Replication(ReplicationConfig(out=tmp_path, seeds=2))
    rep.notes = ["<script>alert(1)</script> & more"]
    rep.sections = {"muscle_activity": "Some <b>text</b>\n\n| a | b |\n| --- | --- |\n"
                                       "| <i>x</i> | 1 |"}
    page = replication_report.report_html(rep)
    assert "<script>" not in page and "<b>text" not in page and "<i>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; more" in page
    assert "<h3>Virtual, first seed: muscle activity</h3>" in page
    assert "<p>Some &lt;b&gt;text&lt;/b&gt;</p>" in page
    assert "<tr><th>a</th><th>b</th></tr>" in page and "<td>&lt;i&gt;x&lt;/i&gt;</td>" in page
    # The claims, the paper's two tables and the section's one, no more (no
    # personalisation section: the run had none).
    assert page.count("<table>") == 4 and "Personalisation" not in page


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
