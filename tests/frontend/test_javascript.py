"""The console's JavaScript: its unit tests (`node --test`) and its linter (ESLint).

Both run from here so that `make test` (pytest) runs them. The vocabulary module the
scripts import is written from the server's own definitions first, as the server would
serve it; numpy's standard deviation gives the stillness test an independent oracle, and
the live stream and the Python message models give the live page's reader its messages.
"""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import subprocess
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from backend.emg.live_envelope import LiveEnvelope
from backend.live.stream import LiveStream
from backend.schemas.lab import LiveMarker, MarkerOut
from backend.schemas.live import (
    DatabaseHealth,
    DeviceHealth,
    Health,
    LiveStatus,
    WorkerHealth,
)
from backend.schemas.vocabulary import javascript_module
from controller.tick_codec import pack
from controller.tick_record import TickRecord

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
ESLINT = ROOT / "frontend" / "node_modules" / ".bin" / "eslint"


def _node() -> str:
    node = shutil.which("node")
    if node is None:
        pytest.fail("node is not installed: `make install` installs it (Debian's npm)")
    return node


def _std_cases(path: Path) -> None:
    """Random hip-angle windows (rad) and numpy's population standard deviation."""
    rng = np.random.default_rng(16)
    cases = []
    for n in (2, 3, 20, 100, 101, 250, 1000):
        for scale in (1e-4, 0.01, 0.3):
            values = rng.normal(0.2, scale, n)
            cases.append({"values": values.tolist(), "std": float(values.std())})
    path.write_text(json.dumps(cases))


def _ticks_message() -> str:
    """A ticks message exactly as the live stream sends it (it writes the JSON itself)."""
    async def send() -> str:
        stream = LiveStream(rate_hz=200.0)
        await stream.start()
        client = stream.connect()
        stream.push(pack([TickRecord(seq=1, t=0.01), TickRecord(seq=2, t=0.02, q_left=0.5)]))
        text = await asyncio.wait_for(client.queue.get(), 5.0)
        await stream.stop()
        return text

    return asyncio.run(send())


def _emg_message() -> str:
    """An EMG envelope message exactly as an EMG inlet publishes it."""
    sent: list[dict[str, object]] = []
    live = LiveEnvelope(2000.0, ["ES-L", "ES-R"], 2, 5, publish=sent.append)
    live.push(np.arange(100) / 2000.0, np.random.default_rng(3).normal(0, 1e-4, (100, 2)))
    return json.dumps(sent[0], allow_nan=False)


def _live_messages(path: Path) -> None:
    """One message of each type the live WebSocket sends, as JSON text."""
    health = Health(status="ok", worker=WorkerHealth(alive=True),
                    device=DeviceHealth(alive=True, kind="simulated"),
                    database=DatabaseHealth(ticks_written=2, write_failures=0), clients=1)
    marker = MarkerOut(id=1, session_id=2, trial_id=3, run_id=4, t=0.02, lsl_time=None,
                       label="start", note="", source="console", stream_id=None,
                       created_at=datetime.now(UTC))
    path.write_text(json.dumps([_ticks_message(), LiveStatus(health=health).model_dump_json(),
                                LiveMarker(marker=marker).model_dump_json(), _emg_message()]))


def test_node_unit_tests_pass(tmp_path: Path) -> None:
    vocabulary = tmp_path / "vocabulary.js"
    vocabulary.write_text(javascript_module())
    cases = tmp_path / "std_cases.json"
    _std_cases(cases)
    live = tmp_path / "live_messages.json"
    _live_messages(live)
    files = sorted(str(p) for p in HERE.glob("*.test.mjs"))
    assert len(files) >= 4, files
    env = {**os.environ, "EXOSTUDY_VOCABULARY": str(vocabulary),
           "EXOSTUDY_STD_CASES": str(cases), "EXOSTUDY_LIVE_MESSAGES": str(live),
           "NODE_NO_WARNINGS": "1"}
    run = subprocess.run(
        [_node(), "--import", str(HERE / "register.mjs"), "--test", "--test-reporter=tap", *files],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    failed = [block for block in run.stdout.split("# Subtest:") if "not ok" in block]
    assert run.returncode == 0, "".join(failed)[-6000:] + run.stderr[-3000:]
    # Every test file ran and none was skipped or left to do.
    assert "# fail 0" in run.stdout and "# skipped 0" in run.stdout and "# todo 0" in run.stdout
    assert f"# pass {run.stdout.count(chr(10) + 'ok ')}" in run.stdout


def test_eslint_finds_nothing() -> None:
    if not ESLINT.is_file():
        pytest.fail(f"{ESLINT} missing: `make install` runs npm ci in frontend/")
    run = subprocess.run(
        [_node(), str(ESLINT), "--max-warnings", "0", "-c", "frontend/eslint.config.mjs",
         "frontend", "tests/frontend"],
        cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-3000:]
