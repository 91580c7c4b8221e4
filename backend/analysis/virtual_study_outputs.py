"""What a virtual study writes into its folder: the sets, each rate setting's tables and
figures (fetched from the server's results endpoints, as a user would download them),
the muscle-activity results of an EMG study, the leave-one-participant-out evaluation,
and the README that puts them together."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from backend.analysis.results import FIGURE_NAMES
from backend.analysis.virtual_study_config import (
    QUESTIONNAIRE_NOTE,
    WRITTEN_TABLES,
    VirtualStudyConfig,
    VirtualStudyReport,
)
from backend.analysis.virtual_study_driver import Driver, ok, ok_bytes, ok_text
from controller.controllers import registry


def write(path: Path, data: bytes | str, report: VirtualStudyReport) -> None:
    """Write one output file and list it in the report."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        path.write_text(data)
    else:
        path.write_bytes(data)
    report.files.append(str(path.relative_to(report.out)))


def write_outputs(d: Driver, cfg: VirtualStudyConfig, studies: dict[str, int], ms_id: int,
                  us_id: int, report: VirtualStudyReport) -> None:
    """Every output of the study but the README and the summary."""
    out = cfg.out
    write(out / "models.json",
          json.dumps(ok(d.c.get(f"/api/model-sets/{ms_id}/document")), indent=1), report)
    write(out / "utilities.json",
          json.dumps(ok(d.c.get(f"/api/utility-sets/{us_id}/document")), indent=1), report)
    for label, sid in studies.items():
        folder = out / label
        doc = ok(d.c.get(f"/api/studies/{sid}/results"))
        write(folder / "results.json", json.dumps(doc, indent=1), report)
        for table in WRITTEN_TABLES:
            for fmt in ("csv", "md"):
                r = d.c.get(f"/api/studies/{sid}/results/{table}.{fmt}")
                write(folder / f"{table}.{fmt}", ok_text(r), report)
        for fig in FIGURE_NAMES:
            for fmt in ("png", "svg"):
                r = d.c.get(f"/api/studies/{sid}/figures/{fig}.{fmt}")
                write(folder / f"{fig}.{fmt}", ok_bytes(r), report)
        if cfg.emg and label == cfg.rates[0]:
            muscle_outputs(d, sid, folder, report)
        first = next((t for t in report.trials
                      if t.study == label and registry.estimates_intent(t.controller)), None)
        if first is not None:
            for fmt in ("png", "svg"):
                r = d.c.get(f"/api/trials/{first.trial_id}/figures/timeline.{fmt}")
                write(folder / f"timeline-trial-{first.trial_id}.{fmt}", ok_bytes(r), report)
    if cfg.model_evaluation:
        sid = next(iter(studies.values()))
        lopo = ok(d.c.get(f"/api/studies/{sid}/model-evaluation",
                          params={"model_set_id": ms_id, "utility_set_id": us_id}))
        write(out / "model_evaluation.json", json.dumps(lopo, indent=1), report)
        write(out / "model_evaluation.md", lopo_markdown(lopo), report)


def muscle_outputs(d: Driver, sid: int, folder: Path, report: VirtualStudyReport) -> None:
    """The muscle-activity results of the EMG study: JSON, every table as CSV, the
    reductions as Markdown, both figures."""
    doc = ok(d.c.get(f"/api/studies/{sid}/muscle-results"))
    write(folder / "muscle_results.json", json.dumps(doc, indent=1), report)
    for table in ("lifts", "summary", "reductions", "repeated_measures"):
        r = d.c.get(f"/api/studies/{sid}/muscle-results/{table}.csv")
        write(folder / f"muscle_{table}.csv", ok_text(r), report)
    r = d.c.get(f"/api/studies/{sid}/muscle-results/reductions.md")
    write(folder / "muscle_reductions.md", ok_text(r), report)
    for fig in ("muscle_envelopes", "muscle_reduction"):
        for fmt in ("png", "svg"):
            r = d.c.get(f"/api/studies/{sid}/muscle-figures/{fig}.{fmt}")
            write(folder / f"{fig}.{fmt}", ok_bytes(r), report)


def lopo_markdown(lopo: dict[str, Any]) -> str:
    """The leave-one-participant-out result as Markdown tables."""
    def pct(x: float | None) -> str:
        return "" if x is None else f"{100 * x:.1f} %"

    lines = ["**Leave-one-participant-out evaluation of the motion models (UMC replay)**", "",
             "| held out | segments | recognised | correct decisions |",
             "| --- | --- | --- | --- |"]
    for f in lopo["folds"]:
        if "error" in f:
            lines.append(f"| {f['participant']} | {f['error']} | | |")
        else:
            lines.append(f"| {f['participant']} | {f['segments']} | {f['recognised']} | "
                         f"{f['correct']} |")
    lines += ["", f"Recognition accuracy {pct(lopo['recognition_accuracy'])}, decision "
              f"accuracy {pct(lopo['decision_accuracy'])} over {lopo['segments']} segments.",
              ""]
    for title, key in (("Recognition (first posterior >= 0.5 in the first half)",
                        "recognition_confusion"),
                       ("First lock decision in the first half", "decision_confusion")):
        conf: dict[str, dict[str, int]] = lopo[key]
        cols = list(next(iter(conf.values())))
        lines += [f"**{title}**", "", "| true \\ predicted | " + " | ".join(cols) + " |",
                  "|" + " --- |" * (len(cols) + 1)]
        lines += [f"| {k} | " + " | ".join(str(v[c]) for c in cols) + " |"
                  for k, v in conf.items()]
        lines.append("")
    return "\n".join(lines)


def readme(cfg: VirtualStudyConfig, report: VirtualStudyReport) -> str:
    """The study folder's README: what ran, how fast, and the tables written."""
    tps = [t.ticks_per_s for t in report.trials]
    lines = [
        "# Virtual study", "",
        f"{cfg.participants} evaluation participants ({cfg.eumc} with E-UMC), "
        f"{cfg.data_participants} data-collection participants, seed {cfg.seed}, "
        f"simulator speed {cfg.speed:g}x, script `{cfg.eval_script}` per trial.", "",
        f"Wall time {report.wall_s:.0f} s (" + ", ".join(
            f"{k} {v:.0f} s" for k, v in report.phases.items()) + ").",
        f"Ticks per second during trials: median {np.median(tps) if tps else math.nan:.0f} "
        f"(requested {cfg.speed * 100:.0f}); device-time gaps: "
        f"{sum(t.gaps for t in report.trials)}.", "",
        "Everything is stored in `study.db` (studies " + ", ".join(
            f"{k}: {v}" for k, v in report.studies.items()) + "); one folder per rate "
        "setting holds the tables (CSV long form, Markdown in the paper's layout) and the "
        "figures (PNG, SVG). `models.json` and `utilities.json` are the sets the trials "
        "used, in the format `exostudy replay` reads.", "", QUESTIONNAIRE_NOTE, "",
    ]
    for label in cfg.rates:
        lines += [f"## {label}", ""]
        for table in ("performance", "false_positives", "onset_to_lock"):
            p = cfg.out / label / f"{table}.md"
            if p.is_file():
                lines += [p.read_text(), ""]
        p = cfg.out / label / "muscle_reductions.md"
        if p.is_file():
            lines += ["### Muscle activity", "",
                      "EMG of the simulated wearer's muscles, published on LSL by the "
                      "simulated amplifier and recorded through the server; the "
                      "reduction of each muscle's mean envelope over the lifts against "
                      "each baseline condition (figures `muscle_reduction.png`, "
                      "`muscle_envelopes.png`; every lift in `muscle_lifts.csv`). The "
                      "simulation does not model the device's mass or straps, so the two "
                      "baselines differ only by chance. The stream is sped up with the "
                      "simulation, so its recordings carry `rate_mismatch`.", "",
                      p.read_text(), ""]
    if (cfg.out / "model_evaluation.md").is_file():
        lines += ["## Motion models, leave one participant out", "",
                  (cfg.out / "model_evaluation.md").read_text()]
    return "\n".join(lines) + "\n"
