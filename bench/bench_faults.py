"""Safety figures for the README's safety table, measured on the real processes.

- server SIGKILL: `exostudy serve` (UDP simulator it spawns) is killed at a random
  moment of its flush cycle; the data lost is the time between the kill and the last
  stored tick's host time (`t_host`, Unix seconds, stamped by the worker);
- worker SIGKILL: time from the signal to the supervisor's exit callback;
- watchdog: the device goes silent mid-lift while locked (its samples stop reaching the
  worker), or the worker is frozen (SIGSTOP) while a lock is held: time from the last
  sample (or the last command) to the first sample the device applies unlocked.

`--busy N` runs N busy-looping processes meanwhile (the machine's cores taken).

    .venv/bin/python bench/bench_faults.py [--kills 6] [--repeats 10] [--busy 2]
        [--only worker,watchdog,server]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import random
import signal
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

# The project's modules are imported inside the functions: the worker is started with
# multiprocessing's "spawn", which imports this file again in the child.


def _spin() -> None:
    while True:
        pass


def _summary(name: str, values_ms: list[float]) -> None:
    v = sorted(values_ms)
    if not v:
        return
    print(f"{name}: n={len(v)} min {v[0]:.0f} ms, median {statistics.median(v):.0f} ms, "
          f"max {v[-1]:.0f} ms", flush=True)


def server_kills(n: int, folder: Path) -> list[float]:
    """Seconds of ticks lost per server SIGKILL."""
    from sqlalchemy import func, select

    from backend import bootstrap
    from backend.db.engine import make_engine
    from backend.db.models import ticks_table
    from tests.faults.served import free_udp_port, serve, wait_for

    models = folder / "models.json"
    bootstrap.ensure_models(models)
    bootstrap.ensure_utilities(bootstrap.utilities_path(folder, 25.0), 25.0)
    lost: list[float] = []
    for i in range(n):
        db_url = f"sqlite:///{folder / f'kill{i}.db'}"
        with serve(folder, db_url, (models, folder), free_udp_port()) as s:
            wait_for(lambda: s.health()["database"]["ticks_written"] > 300, 120, "ticks")
            # Anywhere in the 0.5 s flush cycle.
            time.sleep(random.uniform(0.0, 1.0))
            run_id = s.health()["database"]["current_run_id"]
            kill_at = time.time()
            s.kill()
        engine = make_engine(db_url)
        with engine.connect() as conn:
            last = conn.execute(select(func.max(ticks_table.c.t_host))
                                .where(ticks_table.c.run_id == run_id)).scalar_one()
        engine.dispose()
        lost.append(kill_at - float(last))
    return lost


def worker_kills(n: int) -> list[float]:
    """Seconds from a worker SIGKILL to the supervisor's exit callback."""
    from backend.worker.messages import WorkerConfig
    from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor

    exited = threading.Event()
    seen: list[float] = []
    ticked = threading.Event()
    sup = WorkerSupervisor(WorkerConfig(device_kind="sim"), WorkerCallbacks(
        on_ticks=lambda b: ticked.set(),
        on_exit=lambda code, reason: (seen.append(time.monotonic()), exited.set())))
    out: list[float] = []
    try:
        for _ in range(n):
            ticked.clear()
            exited.clear()
            sup.start()
            if not ticked.wait(60):
                raise RuntimeError("worker did not tick")
            time.sleep(random.uniform(0.0, 0.2))
            pid = sup.state.pid
            assert pid is not None
            t0 = time.monotonic()
            os.kill(pid, signal.SIGKILL)
            if not exited.wait(10):
                raise RuntimeError("worker death not noticed")
            out.append(seen[-1] - t0)
    finally:
        sup.stop()
    return out


def watchdog(n: int, folder: Path) -> tuple[list[float], list[float]]:
    """Silence-to-release seconds: device silent mid-lift; worker frozen."""
    from tests.faults.rig import start_rig, wait_for_lock, wait_release

    rig = start_rig(folder)
    silent: list[float] = []
    frozen: list[float] = []
    try:
        for _ in range(n):
            wait_for_lock(rig)
            rig.relay.mute_device.set()
            since = rig.relay.last_sample_at
            silent.append(wait_release(rig, since) - since)
            rig.relay.mute_device.clear()
            wait_for_lock(rig)
            pid = rig.supervisor.state.pid
            assert pid is not None
            os.kill(pid, signal.SIGSTOP)
            try:
                stopped = time.monotonic()
                released = wait_release(rig, stopped)
                frozen.append(released - rig.relay.last_command_at)
            finally:
                os.kill(pid, signal.SIGCONT)
    finally:
        rig.close()
    return silent, frozen


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kills", type=int, default=5, help="server SIGKILLs")
    p.add_argument("--repeats", type=int, default=10, help="worker kills and watchdog trips")
    p.add_argument("--busy", type=int, default=0, help="busy-looping processes meanwhile")
    p.add_argument("--only", default="worker,watchdog,server",
                   help="comma-separated sections: worker, watchdog, server")
    args = p.parse_args()
    spinners = [mp.Process(target=_spin, daemon=True) for _ in range(args.busy)]
    for sp in spinners:
        sp.start()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            print(f"busy processes: {args.busy}, cores: {os.cpu_count()}", flush=True)
            only = set(args.only.split(","))
            if "worker" in only:
                _summary("worker SIGKILL noticed after",
                         [1e3 * x for x in worker_kills(args.repeats)])
            silent, frozen = watchdog(args.repeats, folder) if "watchdog" in only else ([], [])
            _summary("device silent mid-lift: last sample -> released", [1e3 * x for x in silent])
            _summary("worker frozen (SIGSTOP): last command -> released",
                     [1e3 * x for x in frozen])
            if "server" in only:
                _summary("server SIGKILL: ticks lost (kill time - last stored t_host)",
                         [1e3 * x for x in server_kills(args.kills, folder)])
    finally:
        for sp in spinners:
            sp.terminate()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
