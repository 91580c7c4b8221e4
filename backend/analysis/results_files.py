"""A study's results as files: the tables (CSV and Markdown), the figures (PNG and SVG),
the results document (JSON) and each completed trial's timeline figure.

Used by `exostudy results` on an existing study database, so a researcher gets the
same files the API serves without a running server.
"""

from __future__ import annotations

import json
from pathlib import Path

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from backend.analysis import results
from backend.core.resources import version
from backend.db.evidence_tables import Trial
from backend.db.models import Study
from controller.evaluation.output_folder import OutputFolder


def write_study_results(engine: Engine, db: Session, study_id: int, folder: Path,
                        timelines: bool = True) -> list[Path]:
    """Evaluate study `study_id` and write its result files into `folder`; the paths
    written, in order. Raises `results.ResultsError` for an unknown study."""
    if db.get(Study, study_id) is None:
        known = ", ".join(str(i) for i in db.scalars(select(Study.id).order_by(Study.id)))
        raise results.ResultsError("study", f"no study {study_id} in this database "
                                   f"(studies: {known or 'none'})")
    res = results.study_results(engine, db, study_id)
    files = OutputFolder(folder, private=True)  # participants' data: owner only
    put = files.put

    document = results.results_document(res).model_dump(mode="json")
    # The hardware profile in effect for each evaluated trial (data dictionary:
    # trials.hardware_profile_id), beside the document the results routes also serve.
    profiles = {str(tr.trial_id): getattr(db.get(Trial, tr.trial_id), "hardware_profile_id",
                                          None) for tr in res.trials}
    put("results.json", json.dumps({"exostudy_version": version(), **document,
                                    "hardware_profile_id": profiles}, indent=1))
    for table in results.TABLE_NAMES:
        put(f"{table}.csv", res.csv(table))
        put(f"{table}.md", res.markdown(table))
    for name in results.FIGURE_NAMES:
        fig = res.figure(name)
        put(f"{name}.png", fig.png)
        put(f"{name}.svg", fig.svg)
    if timelines:
        for tr in res.trials:
            trial = db.get(Trial, tr.trial_id)
            if trial is None:
                continue
            try:
                fig = results.timeline_figure(engine, db, trial)
            except results.ResultsError:
                continue  # e.g. no ticks to draw; the tables still count the trial
            put(f"timeline-trial-{trial.id}.png", fig.png)
            put(f"timeline-trial-{trial.id}.svg", fig.svg)
    return files.written
