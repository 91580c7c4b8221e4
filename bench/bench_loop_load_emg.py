"""`bench_loop_load` with EMG: the 100 Hz control loop while 16 channels at 2 kHz stream
in over LSL and are recorded (target: 0 overruns).

The worker is `bench_loop_load`'s (a real worker process, UMC on the in-process
simulated exoskeleton, `paper-evaluation`, real time). Beside it: the simulated EMG
amplifier in a process of its own (`EmgTap`, 16 channels at 2 kHz in 20-sample chunks,
as bench/bench_emg_live.py runs it), and an ExoStudy server app in this process (no
worker of its own) whose session subscribes to the stream, so its EMG inlet records it
to the chunked store and computes the live envelope for the consoles, as during a
live session. Phases: the loop as is; with EMG streaming and recorded; with EMG and one
CPU-bound process per core. Per phase, from the worker's status: overruns added, period
jitter p50/p99/max, compute p99.

    .venv/bin/python bench/bench_loop_load_emg.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
os.environ.setdefault("LSLAPICFG", str(ROOT / "tests" / "backend" / "lab" / "lsl_api.cfg"))

from fastapi.testclient import TestClient  # noqa: E402

from backend import bootstrap  # noqa: E402
from backend.core.config import Settings  # noqa: E402
from backend.main import create_app  # noqa: E402
from backend.worker.messages import WorkerConfig  # noqa: E402
from backend.worker.supervisor import WorkerCallbacks, WorkerSupervisor  # noqa: E402
from bench.bench_emg_live import AMPLIFIER, _montage  # noqa: E402
from bench.bench_loop_load import HOG, _status  # noqa: E402
from bench.record import load_average, record  # noqa: E402
from controller.controllers.spec import ControllerSpec  # noqa: E402
from controller.sim.emg_amplifier import channel_labels  # noqa: E402
from tests.login import PASSWORD, USERNAME, bearer, create_experimenter  # noqa: E402
from tests.polling import wait_for  # noqa: E402

COLUMNS = ["phase", "overruns", "jitter p50 (ms)", "jitter p99 (ms)", "jitter max (ms)",
           "compute p99 (us)", "EMG samples recorded"]


def _phase(sup: WorkerSupervisor, seconds: float, label: str,
           samples: Any = lambda: 0) -> list[object]:
    before = _status(sup).overruns
    n0 = samples()
    time.sleep(seconds)
    st = _status(sup)
    row: list[object] = [label, st.overruns - before, f"{st.jitter_p50_ms:.2f}",
                         f"{st.jitter_p99_ms:.2f}", f"{st.jitter_max_ms:.2f}",
                         f"{st.compute_p99_us:.0f}", samples() - n0]
    print("| " + " | ".join(str(c) for c in row) + " |", flush=True)
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    args = ap.parse_args()
    load0 = load_average()
    tmp = Path(tempfile.mkdtemp(prefix="exostudy-loopbench-emg-"))
    models = tmp / "models.json"
    bootstrap.ensure_models(models)
    utilities = bootstrap.utilities_path(tmp, 25.0)
    bootstrap.ensure_utilities(utilities, 25.0)
    cfg = WorkerConfig(device_kind="sim", device_script="paper-evaluation",
                       spec=ControllerSpec("umc", models_path=str(models),
                                           utilities_path=str(utilities)),
                       models_path=str(models))
    url = f"sqlite:///{tmp}/bench.db"
    create_experimenter(url)
    settings = Settings(database_url=url, start_worker=False,  # type: ignore[call-arg]
                        device_spawn_simulator=False, models_path=models,
                        utilities_dir=tmp, demo=False, emg_dir=tmp / "emg", _env_file=None)
    source = f"bench-loop-emg-{uuid.uuid4().hex[:8]}"
    sup = WorkerSupervisor(cfg, WorkerCallbacks())
    sup.start()
    amp = None
    rows: list[list[object]] = []
    try:
        deadline = time.monotonic() + 60
        while sup.state.status is None or sup.state.status.loop.ticks < 300:
            if time.monotonic() > deadline:
                raise RuntimeError(f"the worker did not start: {sup.state.errors}")
            time.sleep(0.1)
        pid = sup.state.pid
        nice = os.getpriority(os.PRIO_PROCESS, pid) if pid else 0
        raised = "raised" if nice < 0 else "not raised: no privilege"
        print(f"worker pid {pid}, nice {nice} ({raised}); {os.cpu_count()} cores; load "
              f"average {os.getloadavg()[0]:.1f}")
        print("| " + " | ".join(COLUMNS) + " |")
        print("|" + " --- |" * len(COLUMNS))
        rows.append(_phase(sup, args.seconds, "as is (baseline)"))
        amp = subprocess.Popen([sys.executable, "-c", AMPLIFIER, source], cwd=ROOT)
        with TestClient(create_app(settings)) as client:
            client.headers.update(bearer(client, {"username": USERNAME,
                                                  "password": PASSWORD}))
            study = client.post("/api/studies", json={"name": "loop + EMG"}).json()["id"]
            client.put(f"/api/studies/{study}/emg-montage", json=_montage())
            pid_ = client.post(f"/api/studies/{study}/participants",
                               json={"code": "B1"}).json()["id"]
            sess = client.post(f"/api/participants/{pid_}/sessions", json={
                "kind": "evaluation", "precompression_pct": 25}).json()["id"]
            wait_for(lambda: client.post(f"/api/sessions/{sess}/emg-streams", json={
                "name": "BenchEMG", "source_id": source,
                "ignore_labels": channel_labels()[12:]}).status_code == 201, 60,
                "the amplifier visible and subscribed", poll=1.0)
            emg = client.app.state.emg  # type: ignore[attr-defined]
            inlet = next(iter(emg.inlets.values()))
            wait_for(lambda: inlet.samples > 4000, 30, "EMG recorded", poll=0.2)
            rows.append(_phase(sup, args.seconds, "16 ch x 2 kHz EMG recorded",
                               lambda: inlet.samples))
            hogs = [subprocess.Popen([sys.executable, "-c", HOG])
                    for _ in range(os.cpu_count() or 2)]
            try:
                rows.append(_phase(sup, args.seconds, f"EMG + {len(hogs)} CPU hogs",
                                   lambda: inlet.samples))
            finally:
                for h in hogs:
                    h.kill()
                    h.wait()
            recs = client.get(f"/api/sessions/{sess}/emg-recordings").json()
    finally:
        if amp is not None:
            amp.kill()
            amp.wait()
        sup.stop()
    note = (f"worker nice {nice} ({raised}); the EMG is written to "
            f"{len(recs)} recording(s) in the chunked store (2,000 samples/s of 16 "
            "channels nominal, 12 in the montage; the last column counts samples per "
            "channel)")
    record("loop_load_emg", "bench/bench_loop_load_emg.py " + " ".join(sys.argv[1:]),
           COLUMNS, rows, load0, note)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
