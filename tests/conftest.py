"""Fixtures shared by the whole suite: a fresh migrated SQLite file and settings for it."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from fastapi.testclient import TestClient

from backend.core.config import Settings
from tests.processes import fork_servers

if TYPE_CHECKING:
    from tests.databases import AccountTemplates


def pytest_configure(config: pytest.Config) -> None:
    """Collect a test process's garbage less often: its heap holds the whole stack
    (FastAPI, SQLAlchemy, SciPy, numba) and every test allocates thousands of short-lived
    objects, so CPython's default first-generation threshold (700) ran a collection
    every few milliseconds. Measured on `test_access.py` with `test_questionnaires.py`
    (one process, 36 s of CPU): 3.8 s of it in 3,484 collections at the default, 2.1 s
    in 1,646 at these thresholds. The processes the tests start (servers, workers,
    devices) keep the default."""
    import gc

    gc.set_threshold(20_000, 20, 20)


@pytest.fixture(scope="session", autouse=True)
def quick_password_hashes() -> Iterator[None]:
    """Argon2 at its smallest cost for the passwords tests hash and check in this process.

    The server's parameters (64 MiB, 3 passes, 4 lanes) cost about 0.25 s of CPU per
    hash or login, and hundreds of tests create accounts and log in: minutes of the
    suite's CPU spent on a work factor that is a deployment setting, not a behaviour.
    The hashes stay argon2id and carry their parameters, so verification, the
    `$argon2id$` format and the rehash of an older hash are unchanged; a server the
    suite starts as its own process (tests/faults, tests/browser, the wheel) keeps the
    real parameters, and there a cheap template hash is rehashed at its first login,
    as an older hash would be.
    """
    from argon2 import PasswordHasher

    from backend.core import security

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(security, "_hasher",
                      PasswordHasher(time_cost=1, memory_cost=1024, parallelism=1))
        yield


@pytest.fixture(scope="session")
def default_sets(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The embedded default model set and utility folder, built once per test run (by
    the same code a first `make run` uses): under `pytest -n` the first process builds
    them in the run's shared temporary folder, the others wait for it and load them,
    as a server started again loads what its first start wrote (about 3 s of CPU per
    process saved)."""
    import fcntl

    from backend import bootstrap

    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    folder = shared / "defaults"
    folder.mkdir(exist_ok=True)
    models = folder / "models.json"
    with open(shared / "defaults.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        bootstrap.ensure_models(models)
        bootstrap.ensure_utilities(bootstrap.utilities_path(folder, 25.0), 25.0)
    return models, folder


#: Test modules that talk to the database through the storage layer, the API or the
#: migrations: each of their tests runs on SQLite and on PostgreSQL (a throwaway
#: cluster, tests/databases.py). `EXOSTUDY_TEST_DATABASES=sqlite` runs SQLite only.
DATABASE_FACING = {
    "test_migrations", "test_study_records_migration", "test_recorder", "test_studies",
    "test_participants", "test_sessions", "test_questionnaires", "test_preferences",
    "test_audit", "test_auth", "test_access", "test_data_protection", "test_export",
    "test_instrument_ownership_migration", "test_job_lanes_migration", "test_quotas",
    "test_emg_api",
}


#: The modules that take longest, longest first: a fresh clone on this 2-core machine,
#: 2026-11-27 (seconds summed over setup, call and teardown of a module's tests, the
#: larger of two full runs; `make test` prints the 15 slowest). Started longest first, a
#: long module does not begin near the end and run alone while the other processes idle
#: (longest-processing-time-first scheduling); 30 modules cover every one over 45 s.
LONGEST_MODULES = [
    "tests/backend/analysis/test_virtual_study.py",  # 307 s
    "tests/packaging/test_wheel.py",  # 285 s
    "tests/backend/api/test_api_fuzz.py",  # 191 s (56 s alone)
    "tests/faults/test_link_attacks.py",  # 132 s
    "tests/browser/test_console.py",  # 128 s
    "tests/backend/api/test_questionnaires.py",  # 125 s
    "tests/faults/test_prior_faults.py",  # 109 s before it ran sped up
    "tests/backend/api/test_storable_text.py",  # 106 s
    "tests/faults/test_worker_state_faults.py",  # 92 s
    "tests/faults/test_process_faults.py",  # 89 s
    "tests/backend/study/test_access.py",  # 87 s
    "tests/controller/controllers/test_worked_example.py",  # 86 s
    "tests/backend/lab/test_bids_virtual_study.py",  # 79 s
    "tests/backend/api/test_auth.py",  # 71 s
    "tests/faults/test_protocol_faults.py",  # 70 s
    "tests/backend/api/test_roles.py",  # 70 s
    "tests/backend/analysis/test_replication.py",  # 68 s
    "tests/backend/lab/test_xdf_import.py",  # 66 s
    "tests/faults/test_job_faults.py",  # 63 s
    "tests/backend/api/test_wearers_api.py",  # 62 s
    "tests/backend/analysis/test_jobs.py",  # 60 s
    "tests/faults/test_sample_faults.py",  # 58 s
    "tests/backend/api/test_quotas.py",  # 57 s
    "tests/backend/analysis/test_virtual_study_load.py",  # 57 s
    "tests/backend/api/test_study_workflow.py",  # 56 s
    "tests/faults/test_device_gate_faults.py",  # 55 s
    "tests/backend/study/test_data_protection.py",  # 55 s
    "tests/browser/test_access_pages.py",  # 55 s
    "tests/backend/api/test_jobs_api.py",  # 55 s
    "tests/backend/api/test_hardware_api.py",  # 54 s
]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Longest modules first, then the other slow ones. `make test` hands whole modules to
    its processes (`--dist loadfile`) in this order; a long module started last would run
    alone at the end while the other processes idle. The sort is stable, so a module's
    own tests keep their order and stay together."""
    root = Path(str(config.rootpath))
    slow = {item.path for item in items if item.get_closest_marker("slow")}

    longest = {name: i for i, name in enumerate(LONGEST_MODULES)}

    def rank(item: pytest.Item) -> int:
        name = item.path.relative_to(root).as_posix() if item.path.is_relative_to(root) else ""
        if name in longest:
            return longest[name]
        return len(longest) + (0 if item.path in slow else 1)

    items.sort(key=rank)


#: Seconds each test file took (setup, call and teardown of its tests, summed), read at
#: the end of the run so that every change sees what it costs (`make test` prints it).
_FILE_SECONDS: dict[str, float] = {}
SLOWEST_FILES = 15


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Add one phase of one test to its file's total (under xdist this runs in the
    controlling process, once per report a worker sends)."""
    path = report.nodeid.split("::", 1)[0]
    _FILE_SECONDS[path] = _FILE_SECONDS.get(path, 0.0) + report.duration


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """The slowest test files, printed before pytest's closing line."""
    if not _FILE_SECONDS:
        return
    slowest = sorted(_FILE_SECONDS.items(), key=lambda kv: kv[1], reverse=True)[:SLOWEST_FILES]
    terminalreporter.write_sep("=", f"{len(slowest)} slowest test files (seconds, all phases)")
    for path, seconds in slowest:
        terminalreporter.write_line(f"{seconds:8.1f}  {path}")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Run the database-facing modules' tests once per database engine."""
    from tests.databases import postgres_server

    module = metafunc.module.__name__.rsplit(".", 1)[-1]
    wanted = os.environ.get("EXOSTUDY_TEST_DATABASES", "sqlite,postgresql").split(",")
    if ("db_url" in metafunc.fixturenames and module in DATABASE_FACING
            and postgres_server() is None and "postgresql" in wanted):
        metafunc.parametrize("db_url", ["sqlite", "postgresql"], indirect=True)


@pytest.fixture(scope="session")
def postgres_cluster() -> Iterator[str]:
    """A PostgreSQL server for the run: a throwaway cluster started on first use."""
    from tests.databases import ThrowawayCluster

    cluster = ThrowawayCluster()
    try:
        yield cluster.url
    finally:
        cluster.stop()


@pytest.fixture
def db_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """A new, empty database per test (migrations are applied by whoever opens it).

    A SQLite file by default; a fresh database on the throwaway PostgreSQL cluster for
    the `postgresql` runs of the database-facing modules. With `EXOSTUDY_DATABASE_URL`
    pointing at a PostgreSQL server, every test gets a fresh database there instead.
    """
    from tests.databases import fresh_database

    server = None
    if getattr(request, "param", "sqlite") == "postgresql":
        server = request.getfixturevalue("postgres_cluster")
    with fresh_database(tmp_path, server) as url:
        yield url


@pytest.fixture
def settings(db_url: str, default_sets: tuple[Path, Path]) -> Settings:
    """Embedded defaults on a fresh database, without starting a worker."""
    models, folder = default_sets
    return Settings(  # type: ignore[call-arg]
        database_url=db_url, start_worker=False, models_path=models, utilities_dir=folder,
        device_kind="sim", demo=False, _env_file=None,
    )


@pytest.fixture(scope="session")
def account_templates(tmp_path_factory: pytest.TempPathFactory) -> Iterator[AccountTemplates]:
    """Migrated databases holding the default experimenter, one per engine, built on
    first use in each test process."""
    from tests.databases import AccountTemplates

    templates = AccountTemplates(tmp_path_factory.mktemp("account-template"))
    try:
        yield templates
    finally:
        templates.drop()


@pytest.fixture
def experimenter(request: pytest.FixtureRequest, db_url: str,
                 account_templates: AccountTemplates) -> dict[str, str]:
    """An experimenter account in the test database, migrated to hold it: a copy of the
    template database when the test's database is still empty; the credentials as the
    login endpoint takes them."""
    from tests.databases import postgres_server
    from tests.login import PASSWORD, USERNAME, create_experimenter

    server = None
    if not db_url.startswith("sqlite"):
        server = postgres_server() or request.getfixturevalue("postgres_cluster")
    if account_templates.fill(db_url, server):
        return {"username": USERNAME, "password": PASSWORD}
    return create_experimenter(db_url)


@pytest.fixture
def client(settings: Settings, experimenter: dict[str, str]) -> Iterator[TestClient]:
    """A TestClient logged in as `experimenter` (session cookie), with neither worker nor
    simulated device: the study API needs neither, and an idle device process would
    only compete for the CPU."""
    from backend.main import create_app
    from tests.login import log_in

    quiet = settings.model_copy(update={"device_spawn_simulator": False})
    with TestClient(create_app(quiet)) as c:
        log_in(c, experimenter)
        yield c


#: With `EXOSTUDY_TEST_CPU=folder`, each test process writes there the CPU seconds each
#: test file cost it and the processes it started and reaped (servers, workers, devices),
#: as `cpu-<pid>.tsv` (file, wall s, own CPU s, children's CPU s): where the suite's CPU
#: goes, which wall-clock durations on a busy machine do not show.
_CPU_FOLDER = os.environ.get("EXOSTUDY_TEST_CPU", "")
_CPU: dict[str, list[float]] = {}


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Measure one test's CPU when `EXOSTUDY_TEST_CPU` asks for it."""
    if not _CPU_FOLDER:
        yield
        return
    import resource
    import time

    def now() -> tuple[float, float, float]:
        own = resource.getrusage(resource.RUSAGE_SELF)
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        return (time.monotonic(), own.ru_utime + own.ru_stime,
                kids.ru_utime + kids.ru_stime + _fork_server_cpu())

    before = now()
    yield
    after = now()
    row = _CPU.setdefault(item.nodeid.split("::", 1)[0], [0.0, 0.0, 0.0])
    for i in range(3):
        row[i] += after[i] - before[i]


def _fork_server_cpu() -> float:
    """CPU seconds of this process's live fork servers and of the children they have
    reaped (the workers and jobs the servers under test start are the fork server's
    children, so `RUSAGE_CHILDREN` sees them only when the fork server ends)."""
    total = 0.0
    tick = os.sysconf("SC_CLK_TCK")
    for pid in fork_servers("self"):
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        # utime, stime, cutime, cstime: fields 14-17 of stat(5), counted from the state
        # (field 3) here.
        total += sum(int(v) for v in fields[11:15]) / tick
    return total


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Write this process's CPU table (see `_CPU_FOLDER`)."""
    if not (_CPU_FOLDER and _CPU):
        return
    folder = Path(_CPU_FOLDER)
    folder.mkdir(parents=True, exist_ok=True)
    lines = [f"{path}\t{w:.1f}\t{c:.1f}\t{k:.1f}" for path, (w, c, k) in _CPU.items()]
    (folder / f"cpu-{os.getpid()}.tsv").write_text("\n".join(lines) + "\n")
