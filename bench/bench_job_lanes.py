"""Background job lanes: a model fit's wall time alone, and queued behind two
1,000-participant virtual cohorts (the cohort lane runs them in a child process; the
fit runs in the study lane). Also the time from asking for a shutdown to every job
being final with a cohort running.

The fit is the real PPCA fit (`controller.intent.motion_model.fit_model_set`) of demonstrations
from the simulated data collection (collected once beforehand, not timed); the cohorts
are the real cohort computation the console queues. Time is from submitting the job to
its `finished_at` (as a poller sees it).

    .venv/bin/python bench/bench_job_lanes.py [--participants 1000]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.record import load_average, record  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=1000)
    args = ap.parse_args()
    load_before = load_average()

    from backend import bootstrap
    from backend.analysis import cohorts
    from backend.analysis.job_process import run_in_child
    from backend.analysis.jobs import JobRunner, Reporter
    from backend.db import migrate
    from backend.db.engine import make_engine, make_session_factory
    from backend.db.evidence_tables import Job
    from controller.evaluation.cohort import CohortConfig
    from controller.intent.motion_model import fit_model_set
    from controller.sim.demonstrations import collect

    tmp = Path(tempfile.mkdtemp(prefix="bench-jobs-"))
    url = f"sqlite:///{tmp / 'bench.db'}"
    migrate.upgrade(url)
    engine = make_engine(url)
    sessions = make_session_factory(engine)
    models, utilities = tmp / "models.json", bootstrap.utilities_path(tmp, 25.0)
    bootstrap.ensure_models(models)
    bootstrap.ensure_utilities(utilities, 25.0)
    demos = collect((101, 102, 103, 104, 105, 106)).segments
    cfg = CohortConfig(participants=args.participants, seed=1,
                       controllers=("umc", "eumc", "pec"), precompression_pct=25.0)

    def fit(progress: Reporter) -> str:
        fit_model_set(demos)
        return "fitted"

    def cohort(progress: Reporter) -> str:
        run_in_child(cohorts.compute, (cfg, models, utilities), progress, progress.cancelled)
        return "cohort"

    def wall(job_id: int, t0: float) -> float:
        with sessions() as db:
            job = db.get(Job, job_id)
            assert job is not None and job.finished_at is not None, job
        return time.monotonic() - t0

    fit_model_set(demos)  # warm-up (imports, first-call costs): not timed
    runner = JobRunner(sessions)
    t0 = time.monotonic()
    job_id, done = runner.submit("fit_model_set", 1, fit)
    done.result()
    alone = wall(job_id, t0)

    queued = [runner.submit("cohort", n, cohort, lane="cohort")[0] for n in (1, 2)]
    while True:  # the first cohort computing (its child reported progress)
        with sessions() as db:
            first = db.get(Job, queued[0])
            if first is not None and first.progress > 0:
                break
        time.sleep(0.1)
    t0 = time.monotonic()
    job_id, done = runner.submit("fit_model_set", 2, fit)
    done.result()
    behind = wall(job_id, t0)
    with sessions() as db:
        states = [db.get(Job, j).status for j in queued]  # type: ignore[union-attr]

    t0 = time.monotonic()
    runner.shutdown()
    stop = time.monotonic() - t0
    with sessions() as db:
        final = [db.get(Job, j).status for j in queued]  # type: ignore[union-attr]
    engine.dispose()

    rows: list[list[object]] = [
        ["model fit alone", round(alone, 3), ""],
        [f"model fit behind two {args.participants}-participant cohorts", round(behind, 3),
         f"cohorts then: {', '.join(states)}"],
        ["shutdown with a cohort running: every job final", round(stop, 3),
         f"cohorts after: {', '.join(final)}"],
    ]
    for r in rows:
        print(f"{r[0]:<60} {r[1]:>8.3f} s  {r[2]}")
    record("job_lanes", "bench/bench_job_lanes.py " + " ".join(sys.argv[1:]),
           ["case", "wall_s", "note"], rows, load_before)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
