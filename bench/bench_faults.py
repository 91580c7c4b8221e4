"""Safety figures for the safety table (docs/safety.md), measured on the real processes.

- server SIGKILL: `exostudy serve` (UDP simulator it spawns) is killed at a random
  moment of its flush cycle; the data lost is the time between the kill and the last
  stored tick's host time (`t_host`, Unix seconds, stamped by the worker);
- worker SIGKILL: time from the signal to the supervisor's exit callback;
- device SIGKILL: the UDP simulator the server spawned is killed; time until
  `/api/health` says the device is lost;
- watchdog: the device goes silent mid-lift while locked (its samples stop reaching the
  worker), or the worker is frozen (SIGSTOP) while a lock is held: time from the last
  sample (or the last command) to the first sample the device applies unlocked.

`--busy N` runs N busy-looping processes meanwhile (the machine's cores taken).

    .venv/bin/python bench/bench_faults.py [--kills 6] [--repeats 10] [--busy 2]
        [--only worker,device,watchdog,server]
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


def _default_sets(folder: Path) -> Path:
    """The model set (returned) and utility set `exostudy serve` starts with."""
    from backend import bootstrap
    models = folder / "models.json"
    bootstrap.ensure_models(models)
    bootstrap.ensure_utilities(bootstrap.utilities_path(folder, 25.0), 25.0)
    return models


def server_kills(n: int, folder: Path) -> list[float]:
    """Seconds of ticks lost per server SIGKILL."""
    from sqlalchemy import func, select

    from backend.db.engine import make_engine
    from backend.db.models import ticks_table
    from tests.faults.served import serve
    from tests.polling import free_udp_port, wait_for

    models = _default_sets(folder)
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


def device_losses(n: int, folder: Path) -> list[float]:
    """Seconds from SIGKILL of the device process `exostudy serve` spawned to health
    reporting the device lost (one server per repeat)."""
    from tests.faults.served import children, serve
    from tests.polling import free_udp_port, wait_for

    models = _default_sets(folder)
    out: list[float] = []
    for i in range(n):
        db_url = f"sqlite:///{folder / f'device{i}.db'}"
        with serve(folder, db_url, (models, folder), free_udp_port()) as s:
            wait_for(lambda: (h := s.health())["status"] == "ok" and h["worker"]["ticks"] > 100,
                     120, "ticks")
            sims = [p for p in children(s.proc.pid)
                    if b"device-sim" in Path(f"/proc/{p}/cmdline").read_bytes()]
            if len(sims) != 1:
                raise RuntimeError(f"expected one device simulator, found {sims}")
            t0 = time.monotonic()
            os.kill(sims[0], signal.SIGKILL)
            wait_for(lambda: not s.health()["device"]["alive"], 30, "the device loss",
                     poll=0.01)
            out.append(time.monotonic() - t0)
    return out


def watchdog(n: int, folder: Path) -> tuple[list[float], list[float]]:
    """Silence-to-release seconds: device silent mid-lift; worker frozen."""
    from tests.faults.rig import device_goes_silent, start_rig, worker_freezes

    rig = start_rig(folder)
    silent: list[float] = []
    frozen: list[float] = []
    try:
        for _ in range(n):
            since, released = device_goes_silent(rig)
            silent.append(released - since)
            rig.relay.mute_device.clear()
            _, last_command, released = worker_freezes(rig)
            frozen.append(released - last_command)
    finally:
        rig.close()
    return silent, frozen


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kills", type=int, default=5, help="server SIGKILLs")
    p.add_argument("--repeats", type=int, default=10, help="worker kills and watchdog trips")
    p.add_argument("--busy", type=int, default=0, help="busy-looping processes meanwhile")
    p.add_argument("--only", default="worker,device,watchdog,server",
                   help="comma-separated sections: worker, device, watchdog, server")
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
            if "device" in only:
                _summary("device process SIGKILL: health says device lost after",
                         [1e3 * x for x in device_losses(args.repeats, folder)])
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
