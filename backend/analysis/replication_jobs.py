"""Replication reports started from the console: the `cohort` engine of
`backend.analysis.replication_run` on the job runner's cohort lane, in a child process, each
report in its own folder under `<run_dir>/replication/`.

Only the `cohort` engine runs from the console: the `study` engine starts a server and
a worker of its own per seed, which a running server should not do inside itself
(`exostudy replicate` on the command line runs it).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.analysis.job_process import run_in_child
from backend.analysis.jobs import JobRunner, QuotaFullError, Reporter
from backend.core.errors import ConflictError
from backend.db.evidence_tables import Job
from backend.db.models import User
from controller.private_files import PRIVATE_DIR, make_private_dir

JOB_KIND = "replication"
#: The newest report is read from here; report folders are named by their start time.
FOLDER = "replication"


def reports_dir(run_dir: Path) -> Path:
    """Where the console's reports are written."""
    return run_dir / FOLDER


def compute(out: Path, seeds: int, participants: int, progress: Any) -> str:
    """The report (runs in the job's child process, so it takes picklable values)."""
    # Deferred: the replication loads the simulator and matplotlib, which only the
    # job's child process needs (the server imports this module at start-up).
    from backend.analysis.replication_config import ReplicationConfig
    from backend.analysis.replication_run import run
    from controller.evaluation.paper_claims import verdict_counts

    eumc = min(3, participants)
    # The personalisation section (beyond the paper) is left out of the console's report
    # for now: the API has no setting for its size yet, and it would add minutes.
    cfg = ReplicationConfig(out=out, seeds=seeds, engine="cohort", participants=participants,
                            eumc=eumc, personalisation_participants=0)
    rep = run(cfg, log=lambda _m: None, progress=progress)
    return f"{verdict_counts(rep.claims)}, in {rep.wall_s:.0f} s"


def start(jobs: JobRunner, user: User, run_dir: Path, seeds: int, participants: int,
          per_account: int) -> tuple[int, Path]:
    """Queue a report on the cohort lane; the job id and the report's folder. Refused
    (`ConflictError`, a 409) while the account has `per_account` reports queued or
    running, whatever its role: a report takes minutes of the server's CPU.

    The folder is made when the report is queued, named by the time and the job's id
    and created exclusively, so two reports started in the same second never share one."""
    try:
        job_id = jobs.reserve(JOB_KIND, lane="cohort", owner_id=user.id, quota=per_account)
    except QuotaFullError as exc:
        raise ConflictError("replication", f"account {user.username} already has "
                            f"{len(exc.unfinished)} unfinished replication report(s) (jobs "
                            f"{exc.unfinished}); at most {per_account} may be queued or "
                            "running per account (setting replication_jobs_per_account): "
                            "wait for one to finish") from None
    try:
        out = _new_folder(reports_dir(run_dir), f"{time.strftime('%Y%m%d-%H%M%S')}-job"
                          f"{job_id}-seeds{seeds}")
    except BaseException:
        jobs.abandon(job_id, "cancelled: the report's folder could not be made")
        raise

    def work(progress: Reporter) -> str:
        message: str = run_in_child(compute, (out, seeds, participants), progress,
                                    progress.cancelled)
        return message

    jobs.enqueue(job_id, work)
    return job_id, out


def _new_folder(root: Path, name: str) -> Path:
    """A folder under `root` that did not exist before (0700), `name` or `name-2`..."""
    make_private_dir(root)
    for n in range(1, 1000):
        folder = root / (name if n == 1 else f"{name}-{n}")
        try:
            folder.mkdir(mode=PRIVATE_DIR)
        except FileExistsError:
            continue
        os.chmod(folder, PRIVATE_DIR)
        return folder
    raise ConflictError("replication", f"no free folder name for {name} in {root}")


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
                                               "unit", "interval", "verdict", "reason",
                                               "difference", "unstable")}
                       for c in doc.get("claims", [])]}
