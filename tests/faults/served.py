"""The server as users start it (`exostudy serve`) in its own process, for faults that
kill it; and direct database set-ups the fault tests share."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from backend.db.engine import make_engine
from backend.db.evidence_tables import Trial
from backend.db.models import Participant, Study, StudyMember, StudySession, User, ticks_table
from tests.polling import free_tcp_port, wait_for

EXOSTUDY = Path(sys.executable).with_name("exostudy")


def alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie does not count)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in status


def children(pid: int) -> list[int]:
    """Direct children of `pid` (from /proc)."""
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except FileNotFoundError:
        return []
    return [int(x) for x in text.split()]


class Served:
    """One `exostudy serve` process and an authenticated client for it."""

    def __init__(self, proc: subprocess.Popen[bytes], base: str, log: Path) -> None:
        self.proc = proc
        self.base = base
        self.log = log
        self.client = httpx.Client(base_url=base, timeout=60.0)

    def log_in(self, credentials: dict[str, str]) -> None:
        """Bearer token for every later request."""
        r = self.client.post("/api/auth/token", json=credentials)
        assert r.status_code == 200, r.text
        self.client.headers["Authorization"] = f"Bearer {r.json()['access_token']}"

    def health(self) -> dict[str, Any]:
        body: dict[str, Any] = self.client.get("/api/health").json()
        return body

    def kill(self) -> None:
        """SIGKILL: no shutdown code runs."""
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(10)
        self.client.close()


@contextmanager
def serve(tmp_path: Path, db_url: str, default_sets: tuple[Path, Path], device_port: int,
          **env: str) -> Iterator[Served]:
    """`exostudy serve` on a free port with a UDP device simulator it spawns on
    `device_port`; killed (if still running) afterwards."""
    models, folder = default_sets
    port = free_tcp_port()
    full_env = dict(os.environ,
                    EXOSTUDY_DATABASE_URL=db_url, EXOSTUDY_MODELS_PATH=str(models),
                    EXOSTUDY_UTILITIES_DIR=str(folder), EXOSTUDY_DEMO="false",
                    EXOSTUDY_DEVICE_KIND="udp", EXOSTUDY_DEVICE_ADDRESS=f"127.0.0.1:{device_port}",
                    EXOSTUDY_RUN_DIR=str(tmp_path / "var"),
                    EXOSTUDY_DEVICE_KEY_FILE=str(tmp_path / "var" / "device.key"), **env)
    log = tmp_path / f"server-{port}.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen([str(EXOSTUDY), "serve", "--port", str(port),
                                 "--log-level", "warning"],
                                cwd=tmp_path, env=full_env, stdout=out, stderr=subprocess.STDOUT)
    served = Served(proc, f"http://127.0.0.1:{port}", log)

    def up() -> bool:
        if proc.poll() is not None:
            raise AssertionError(f"server exited: {log.read_text()[-2000:]}")
        try:
            return served.client.get("/api/health").status_code == 200
        except httpx.HTTPError:
            return False

    try:
        wait_for(up, 90, "the server to answer", poll=0.2)
        yield served
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(10)
        served.client.close()


def make_trials(db_url: str, username: str, controllers: tuple[str, ...] = ("pec",),
                task: str = "squat-sequence") -> list[int]:
    """A study, participant and evaluation session with planned trials of `controllers`
    (the user owns the study); returns the trial ids in order."""
    engine = make_engine(db_url)
    with Session(engine) as db:
        user = db.scalars(select(User).where(User.username == username)).one()
        n = db.scalar(select(func.count()).select_from(Study)) or 0
        study = Study(name=f"faults {n + 1}", created_by=user.id)
        db.add(study)
        db.flush()
        db.add(StudyMember(study_id=study.id, user_id=user.id, role="owner"))
        part = Participant(study_id=study.id, code=f"F{n + 1:02d}")
        db.add(part)
        db.flush()
        sess = StudySession(participant_id=part.id, kind="evaluation", precompression_pct=25.0)
        db.add(sess)
        db.flush()
        trials = [Trial(session_id=sess.id, controller=c, task=task, planned_order=i,
                        status="planned") for i, c in enumerate(controllers)]
        db.add_all(trials)
        db.commit()
        ids = [t.id for t in trials]
    engine.dispose()
    return ids


def stored_ticks(db_url: str, run_id: int, column: str = "t") -> list[Any]:
    """One column of a run's stored ticks, in id order."""
    engine = make_engine(db_url)
    with engine.connect() as conn:
        rows = conn.execute(select(ticks_table.c[column]).where(ticks_table.c.run_id == run_id)
                            .order_by(ticks_table.c.id)).scalars().all()
    engine.dispose()
    return list(rows)
