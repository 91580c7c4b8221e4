"""One settings object, read from the environment (prefix `EXOSTUDY_`) and `.env`.

Every default is the embedded one a newcomer gets from `make run`: a SQLite file under
`var/`, a simulated exoskeleton, the server on 127.0.0.1:8000.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from backend.core import resources
from controller.device.base import MAX_SPEED

PROJECT_ROOT = Path(__file__).resolve().parents[2]
#: Default home of the database, keys, models and pid files: `var/` in a clone, the
#: platform data folder when installed from a wheel (backend/core/resources.py).
DATA_DIR = resources.data_dir()


class Settings(BaseSettings):
    """Server configuration. `EXOSTUDY_DATABASE_URL=... exostudy serve` overrides a field."""

    model_config = SettingsConfigDict(env_prefix="EXOSTUDY_", env_file=".env", extra="ignore")

    database_url: str = f"sqlite:///{DATA_DIR / 'exostudy.db'}"
    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=0, le=65535)

    #: `udp`: the worker talks to a device over the wire protocol at `device_address`
    #: (docs/device-protocol.md). `sim`: the simulated exoskeleton runs inside the worker.
    device_kind: Literal["sim", "udp"] = "udp"
    device_address: str = "127.0.0.1:5555"
    #: With `udp`, start the simulated exoskeleton as its own process on that address.
    #: Set it to false for a real exoskeleton.
    device_spawn_simulator: bool = True
    #: Which simulated device is spawned: the Python reference (`python`) or the C
    #: firmware core built for Linux against the same simulated wearer (`c`:
    #: firmware/build/exostudy-device, built by `make install`; docs/device-firmware.md).
    device_implementation: Literal["python", "c"] = "python"
    device_seed: int = 1
    device_script: str = "paper-evaluation"
    #: The key that authenticates every packet of the device link (HMAC-SHA256): 64 hex
    #: digits, created at first start with mode 0600, given to the spawned simulator.
    #: For real hardware, the firmware is provisioned with the same key.
    device_key_file: Path = DATA_DIR / "device.key"
    precompression_pct: float = Field(default=25.0, ge=0.0, le=100.0)
    #: With `sim`: run the simulated wearer this many times faster than real time.
    device_speed: float = Field(default=1.0, ge=0.1, le=MAX_SPEED)
    #: With `sim`: the simulated wearer's muscles on LSL as a 16-channel EMG amplifier
    #: (type EMG, 2 kHz), generated only while an inlet records it (docs/muscle-activity.md).
    device_emg_lsl: bool = False

    #: Controller the worker starts with: none, umc, eumc or pec.
    controller: str = "none"
    #: Run every controller at this rate (Hz) instead of the paper's rates.
    controller_rate_hz: float | None = Field(default=None, gt=0.0, le=100.0)
    #: Model set for UMC and E-UMC; built from simulated demonstrations if missing.
    models_path: Path = DATA_DIR / "models" / "sim-default.json"
    #: Folder of default utility sets (one per precompression), built if missing.
    utilities_dir: Path = DATA_DIR / "utilities"

    #: Messages per second sent to each browser (each carries every tick since the last).
    # 60: above the worker's 50 batches a second, so the budget never holds a batch back
    # (bench/bench_live.py: p95 23-34 ms with 4 consoles, against 41-48 ms at 40).
    stream_rate: float = Field(default=60.0, gt=0.0, le=100.0)
    #: Queue length per browser before the oldest message is dropped.
    stream_queue: int = Field(default=60, ge=1)
    #: Longest time (s) ticks wait in memory before they are written to the database.
    #: A killed server loses this plus the pipe and the write itself: with 0.5 s,
    #: bench/bench_faults.py measured up to 0.54 s lost on a loaded machine; 0.25 s keeps
    #: the loss under the 0.5 s the safety table promises.
    db_flush_interval: float = Field(default=0.25, gt=0.0, le=1.0)

    #: Publish the tick and marker streams on the Lab Streaming Layer (LabRecorder
    #: records them beside the lab's other devices) and read subscribed marker streams.
    lsl_enabled: bool = True
    #: Name of the LSL tick stream; the marker stream is NAME-Markers. Two servers on
    #: one network need different names.
    lsl_name: str = Field(default="ExoStudy", min_length=1, max_length=100)

    #: Create the demo study and account in an empty database (see backend/study/demo.py).
    demo: bool = True

    #: Origins (besides the server's own host) whose pages may send cookie-authenticated
    #: changes and open WebSockets, e.g. ["https://exo.lab.example"] behind a proxy that
    #: rewrites the Host header. Empty: same host only.
    allowed_origins: list[str] = []
    #: Always set the `Secure` flag on the session cookie (behind a TLS-terminating
    #: proxy, where the app itself sees plain http).
    secure_cookies: bool = False
    #: Largest request body (bytes) read before 413; JSON bodies are small.
    max_body_bytes: int = Field(default=1_000_000, ge=1024)
    #: Larger limit for file uploads (utility-set import, data files).
    max_upload_bytes: int = Field(default=64_000_000, ge=1024)
    #: What one attached XDF file may make the reader build (backend/lab/xdf_reader.py);
    #: a file beyond any of these is refused with 422. Streams: LabRecorder sessions
    #: record a few to a few dozen.
    xdf_max_streams: int = Field(default=100, ge=1, le=100_000)
    #: Chunks: LabRecorder writes about two a second per stream, plus a clock offset
    #: every 5 s and a boundary every 10 s; a file within the upload limit has far fewer.
    xdf_max_chunks: int = Field(default=1_000_000, ge=1)
    #: Samples of all streams together: 64 MB of the most compact samples (one int8
    #: channel with its time stamp, 10 bytes) is 6.4 million.
    xdf_max_samples: int = Field(default=20_000_000, ge=1)
    #: Clock offsets of all streams together: one per stream every 5 s, so 50,000 is
    #: about 7 hours of 10 streams.
    xdf_max_clock_offsets: int = Field(default=50_000, ge=0)
    #: Bytes the decoded streams may take (time stamps and values): a 64 MB file of double
    #: samples decodes to about 70 MB. The reading process may use twice this and 512 MB.
    xdf_max_decoded_bytes: int = Field(default=1024**3, ge=1024)
    #: Channels one stream may declare: high-density EEG or EMG has a few hundred, motion
    #: capture of 100 markers 300.
    xdf_max_channels: int = Field(default=4096, ge=1, le=65_536)
    #: Bytes of one stream header's XML: a label, unit and type for each of 4,096
    #: channels take about 400 kB.
    xdf_max_header_bytes: int = Field(default=1024**2, ge=1024, le=16 * 1024**2)
    #: Channel labels of each stream kept in the stored summary (each cut to 64
    #: characters; the summary also says how many there are).
    xdf_summary_channels: int = Field(default=64, ge=0, le=4096)
    #: Largest stored summary of one file (bytes of JSON): 100 streams of 64 plain labels
    #: take about 510 kB.
    xdf_max_summary_bytes: int = Field(default=1024**2, ge=1024)
    #: Longest (s) the reading process may take before the file is refused; a 64 MB
    #: recording takes a few seconds.
    xdf_parse_seconds: float = Field(default=120.0, gt=0.0, le=3600.0)
    #: Where an upload is written for the reading process (folders 0700, files 0600,
    #: removed after each import).
    xdf_work_dir: Path = DATA_DIR / "xdf-work"
    #: Folder of the EMG recording files (None: `emg/` beside a SQLite database file, or
    #: in the data folder for PostgreSQL); `backend.emg.store`.
    emg_dir: Path | None = None

    #: Start the control worker with the server (tests switch it off).
    start_worker: bool = True
    frontend_dir: Path = resources.frontend_dir()
    #: Pid and log files of the spawned device simulator (a restarted server stops a
    #: simulator its predecessor left behind, found through the pid file).
    run_dir: Path = DATA_DIR
    #: Most ticks kept in memory while the database refuses writes: 5 min at 100 Hz,
    #: about 40 MB (1.3 kB a received tick, measured with tracemalloc). Beyond it the
    #: oldest are dropped and counted in health; the worker keeps controlling.
    db_backlog_limit: int = Field(default=30_000, ge=100)
    #: Virtual cohorts one account may have queued or running at once (one runs at a
    #: time in the cohort lane, so 3 is one running and two waiting; a 1,000-participant
    #: cohort takes minutes). Beyond it, `POST /api/cohorts` answers 409.
    cohort_jobs_per_account: int = Field(default=3, ge=1, le=100)
    #: Replication reports one account (any role) may have queued or running at once;
    #: they share the cohort lane and take minutes each. Beyond it, `POST
    #: /api/replication` answers 409.
    replication_jobs_per_account: int = Field(default=2, ge=1, le=100)

    @field_validator("device_address")
    @classmethod
    def _host_port(cls, v: str) -> str:
        host, sep, port = v.rpartition(":")
        if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"device_address must be HOST:PORT, got {v!r}")
        return v

    @property
    def device_host_port(self) -> tuple[str, int]:
        """`device_address` split into host and port."""
        host, _, port = self.device_address.rpartition(":")
        return host, int(port)


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings (tests build their own `Settings` instead)."""
    return Settings()
