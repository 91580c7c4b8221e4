"""Replication reports started from the console: the `cohort` engine of
`backend.analysis.replication` on the job runner's cohort lane, in a child process, each
report in its own folder under `<run_dir>/replication/`.

Only the `cohort` engine runs from the console: the `study` engine starts a server and
a worker of its own per seed, which a running server should not do inside itself
(`exostudy replicate` on the command line runs it).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.analysis.jobs import JobRunner, Reporter
from backend.db.evidence_tables import Job
from backend.db.models import User

JOB_KIND = "replication"
#: The newest report is read from here; report folders are named by their start time.
FOLDER = "replication"


def reports_dir(run_dir: Path) -> Path:
    """Where the console's reports are written."""
    return run_dir / FOLDER


def compute(out: Path, seeds: int, participants: int, progress: Any) -> str:
    """The report (runs in the job's child process, so it takes picklable values)."""
    from backend.analysis.replication import ReplicationConfig, run

    eumc = min(3, participants)
    cfg = ReplicationConfig(out=out, seeds=seeds, engine="cohort", participants=participants,
                            eumc=eumc)
    rep = run(cfg, log=lambda _m: None, progress=progress)
    counts = {v: sum(1 for c in rep.claims if c.verdict.value == v)
              for v in ("reproduced", "differs", "not simulated")}
    return (f"{counts['reproduced']} reproduced, {counts['differs']} differ, "
            f"{counts['not simulated']} not simulated, in {rep.wall_s:.0f} s")


def start(jobs: JobRunner, user: User, run_dir: Path, seeds: int,
          participants: int) -> tuple[int, Path]:
    """Queue a report on the cohort lane; the job id and the report's folder."""
    from backend.analysis.job_process import run_in_child

    out = reports_dir(run_dir) / f"{time.strftime('%Y%m%d-%H%M%S')}-seeds{seeds}"
    if out.exists():
        out = out.with_name(f"{out.name}-{time.monotonic_ns()}")

    def work(progress: Reporter) -> str:
        out.mkdir(parents=True, exist_ok=True)
        message: str = run_in_child(compute, (out, seeds, participants), progress,
                                    progress.cancelled)
        return message

    job_id, _ = jobs.submit(JOB_KIND, 0, work, lane="cohort", owner_id=user.id)
    return job_id, out


def latest_job(db: Session) -> Job | None:
    """The newest replication job, whatever its state."""
    return db.scalars(select(Job).where(Job.kind == JOB_KIND).order_by(Job.id.desc())).first()


def latest_report(run_dir: Path) -> Path | None:
    """The newest folder holding a finished report (`replication.json` is written with
    the report, after every figure)."""
    root = reports_dir(run_dir)
    if not root.is_dir():
        return None
    done = [p for p in root.iterdir() if (p / "replication.json").is_file()
            and (p / "report.html").is_file()]
    return max(done, key=lambda p: (p / "replication.json").stat().st_mtime, default=None)


def summary(folder: Path) -> dict[str, Any]:
    """The report's claims and run facts, for the console page."""
    doc = json.loads((folder / "replication.json").read_text())
    return {"folder": folder.name, "wall_s": doc.get("wall_s"), "config": doc.get("config"),
            "claims": [{k: c.get(k) for k in ("key", "source", "statement", "kind", "paper",
                                               "unit", "interval", "verdict", "reason")}
                       for c in doc.get("claims", [])]}
