"""The wheel is the application: built with `python -m build`, installed into a new
virtual environment with no clone on its path, it migrates a database, serves the
console (pages, modules, uPlot, /docs, the guide) with the worker and the spawned UDP
device simulator, runs a small virtual study, and writes that study's results, its BIDS
export and a small virtual cohort.

Speed: the new environment borrows the dependencies already installed in the test's
own environment (a `.pth` line naming its site-packages, which adds the folder without
running the editable install's hook there), and the wheel goes in with `--no-deps`, so
the test costs the build and the runs, not a download of numpy and scipy; the wheel is
built in the test's environment too (`--no-isolation`: `build`, `setuptools`, `wheel`
and `mkdocs` are dev dependencies, so `build` is not asked to check them: `-x`), and the
clone's compiled numba kernels are copied beside the wheel's copies of their sources
(`_borrow_compiled_kernels`). `EXOSTUDY_WHEEL_TEST_FULL=1` builds in an isolated
environment, installs the dependencies from the index and compiles every kernel in the
new environment instead, as a user does.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import sysconfig
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import httpx
import pytest

from tests.polling import free_tcp_port, free_udp_port, wait_for

ROOT = Path(__file__).resolve().parents[2]
PASSWORD = "wheel-test-password-7841"

# Slow, and each step waits on a real build, install or study: the suite's 300 s limit
# per test is too short for the virtual study on a loaded machine.
pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]


@dataclass(frozen=True)
class Installed:
    """A virtual environment holding the wheel, and a clean environment to run it in."""

    venv: Path
    env: dict[str, str]
    cwd: Path
    data: Path
    wheel: Path

    def run(self, *args: str, stdin: str | None = None, timeout: float = 300
            ) -> subprocess.CompletedProcess[str]:
        # The usual umask (files 0644, folders 0755): the data must be private anyway.
        proc = subprocess.run([str(self.venv / "bin" / "exostudy"), *args], cwd=self.cwd,
                              env=self.env, input=stdin, capture_output=True, text=True,
                              timeout=timeout, check=False, umask=0o022)
        assert proc.returncode == 0, (args, proc.stdout[-3000:], proc.stderr[-3000:])
        return proc

    @cached_property
    def version_line(self) -> str:
        """What `exostudy --version` prints, asked once (each run imports the CLI)."""
        return self.run("--version").stdout.strip()

    @property
    def version(self) -> str:
        """The number in the version line."""
        return self.version_line.split()[1]


#: The one module whose kernel the new environment compiles and caches itself (the
#: cohort's rank test, about 1 s of CPU), so that compiling into the installed package's
#: own `__pycache__` stays checked (`test_results_export_and_cohort_from_the_wheel`).
COMPILED_HERE = "controller/evaluation/cohort_stats.py"


def _borrow_compiled_kernels(purelib: Path) -> None:
    """Copy the clone's numba cache into the `__pycache__` folders beside the installed
    sources.

    Every kernel is `@njit(cache=True)`, cached beside its source and used while the
    source's content (numba hashes it) and the function's bytecode are those it was
    compiled from; the wheel's sources are the clone's, byte for byte. Without this the
    new environment compiled every kernel again, one process after another (the server,
    the study's worker, the cohort): about 27 s of CPU, a third of the module's. Only a
    module whose source is still the wheel's lends its kernels (an edit since the build
    could otherwise race numba's rewrite of them); a kernel the clone has not compiled is
    compiled as before."""
    for package in ("backend", "controller"):
        for cache in (ROOT / package).rglob("__pycache__"):
            target = purelib / cache.relative_to(ROOT)
            for kernel in sorted([*cache.glob("*.nbc"), *cache.glob("*.nbi")]):
                module = kernel.name.split(".", 1)[0] + ".py"
                if (cache.parent / module).relative_to(ROOT).as_posix() == COMPILED_HERE:
                    continue
                source, installed = cache.parent / module, target.parent / module
                if (installed.is_file() and source.is_file()
                        and installed.read_bytes() == source.read_bytes()):
                    target.mkdir(exist_ok=True)
                    shutil.copyfile(kernel, target / kernel.name)


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    """Build the wheel from this clone and install it into a new venv."""
    tmp = tmp_path_factory.mktemp("wheel")
    dist = tmp / "dist"
    build_env = {k: v for k, v in os.environ.items() if not k.startswith("EXOSTUDY_")}
    build_env["NO_MKDOCS_2_WARNING"] = "1"
    full = os.environ.get("EXOSTUDY_WHEEL_TEST_FULL") == "1"
    # The dev environment holds the build requirements (mkdocs, setuptools, wheel), so
    # the quick path builds in it; the full path builds as a user does, isolated.
    isolation = [] if full else ["--no-isolation", "--skip-dependency-check"]
    proc = subprocess.run([sys.executable, "-m", "build", "--wheel", *isolation, "--outdir",
                           str(dist), str(ROOT)], cwd=ROOT, env=build_env,
                          capture_output=True, text=True, timeout=900, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    wheels = list(dist.glob("exostudy-*-py3-none-any.whl"))
    assert len(wheels) == 1, wheels

    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    if full:
        subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install",
                        "--quiet", "--no-compile", str(wheels[0])], check=True, timeout=1200)
    else:
        purelib = Path(sysconfig.get_paths()["purelib"])
        new_purelib = Path(subprocess.run(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True, text=True, check=True).stdout.strip())
        (new_purelib / "zz_borrowed_dependencies.pth").write_text(f"{purelib}\n")
        # The borrowed pip, run by the new interpreter: what `pip --python` does, without
        # the process that hands over to it.
        subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--no-compile",
                        "--no-deps", str(wheels[0])], check=True, timeout=600)
        _borrow_compiled_kernels(new_purelib)

    cwd = tmp / "elsewhere"
    cwd.mkdir()
    data = tmp / "xdg-data"
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("EXOSTUDY_", "PYTHON", "VIRTUAL_ENV"))}
    env.update(HOME=str(tmp / "home"), XDG_DATA_HOME=str(data), EXOSTUDY_LSL_ENABLED="false",
               PATH=f"{venv / 'bin'}:{env.get('PATH', '/usr/bin:/bin')}")
    return Installed(venv, env, cwd, data, wheels[0])


def test_the_wheel_carries_the_application_and_not_the_clone(installed: Installed) -> None:
    line = installed.version_line
    assert re.fullmatch(r"exostudy \d+\.\d+\.\d+\S*", line), line
    assert installed.wheel.name.startswith(f"exostudy-{installed.version}-")
    where = subprocess.run(
        [str(installed.venv / "bin" / "python"), "-c",
         "import backend, controller; from backend.core import resources as r; "
         "print(backend.__file__, controller.__file__, r.installed(), r.frontend_dir(), "
         "r.migrations_dir(), r.guide_dir(), r.data_dir())"],
        cwd=installed.cwd, env=installed.env, capture_output=True, text=True, check=True)
    backend_file, controller_file, bundled, *dirs = where.stdout.split()
    site = str(installed.venv)
    assert backend_file.startswith(site) and controller_file.startswith(site)
    assert bundled == "True"
    front, migrations, guide, data = (Path(d) for d in dirs)
    for d in (front, migrations, guide):
        assert str(d).startswith(site) and d.is_dir(), d
    assert data == installed.data / "exostudy"
    assert (migrations / "env.py").is_file() and list((migrations / "versions").glob("0*.py"))
    assert (front / "node_modules" / "uplot" / "LICENSE").is_file()
    # Package data: the replication report's template is rendered at run time.
    assert "backend/analysis/templates/replication_report.html.j2" in zipfile.ZipFile(
        installed.wheel).namelist()


def test_db_upgrade_makes_the_database_in_the_data_folder(installed: Installed) -> None:
    out = installed.run("db", "upgrade").stdout
    db = installed.data / "exostudy" / "exostudy.db"
    assert db.is_file() and str(db) in out
    head = re.search(r"at revision (\w+)", out)
    assert head and head.group(1) != "None"
    assert installed.run("db", "current").stdout.strip() == head.group(1)
    # Readable by its owner only, though the umask would have given 0644 and 0755.
    assert oct(stat.S_IMODE(db.stat().st_mode)) == "0o600"
    assert oct(stat.S_IMODE(db.parent.stat().st_mode)) == "0o700"
    assert installed.run("doctor").stdout.startswith("ok: ")


@pytest.fixture
def served(installed: Installed) -> Iterator[str]:
    """`exostudy serve` from the wheel, with its worker and a spawned UDP simulator.

    One test's: kept for the module, the server, its worker and the simulator went on
    ticking at 100 Hz through the virtual study and the cohort (10 to 20 s of CPU alone,
    more on a loaded machine, and they competed with the study for the cores). `user add`
    brings the database to the newest revision itself (no `db upgrade` first)."""
    installed.run("user", "add", "wheel", "--admin", stdin=PASSWORD + "\n")
    port = free_tcp_port()
    env = dict(installed.env, EXOSTUDY_DEMO="false",
               EXOSTUDY_DEVICE_ADDRESS=f"127.0.0.1:{free_udp_port()}")
    log = installed.cwd / "serve.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen([str(installed.venv / "bin" / "exostudy"), "serve", "--port",
                                 str(port), "--log-level", "warning"], cwd=installed.cwd,
                                env=env, stdout=out, stderr=subprocess.STDOUT,
                                umask=0o022)
    base = f"http://127.0.0.1:{port}"
    # One client for the polls: `httpx.get` builds a client (and its TLS context) per
    # call, 30 ms of CPU each, a sixth of a core at this rate while the server starts.
    poller = httpx.Client(base_url=base, timeout=5)

    def up() -> bool:
        if proc.poll() is not None:
            raise AssertionError(f"server exited: {log.read_text()[-3000:]}")
        try:
            return poller.get("/api/health").status_code == 200
        except httpx.HTTPError:
            return False

    try:
        with poller:
            wait_for(up, 180, "the installed server to answer", poll=0.2)
        yield base
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


def test_serve_from_the_wheel(installed: Installed, served: str) -> None:
    with httpx.Client(base_url=served, timeout=30) as c:
        login = c.get("/login")
        assert login.status_code == 200 and 'id="password"' in login.text
        assert c.get("/console", follow_redirects=False).status_code == 303  # login first
        r = c.post("/api/auth/login", json={"username": "wheel", "password": PASSWORD})
        assert r.status_code == 200, r.text
        console = c.get("/console")
        assert console.status_code == 200 and "/static/guard.js" in console.text
        for path, marker in (("/static/api.js", "export"),
                             ("/static/favicon.svg", "<svg"),
                             ("/static/vocabulary.js", "export"),
                             ("/vendor/uplot/uPlot.esm.js", "uPlot"),
                             ("/vendor/uplot/uPlot.min.css", ".uplot"),
                             ("/docs", "swagger-ui"),
                             ("/docs-assets/swagger-ui-bundle.js", "SwaggerUIBundle"),
                             ("/guide/index.html", "ExoStudy"),
                             ("/guide/search/search_index.json", "getting-started")):
            r = c.get(path)
            assert r.status_code == 200 and marker in r.text, (path, r.status_code)
        # While it serves, SQLite's write-ahead log and shared memory sit beside the
        # database, private like it.
        data = installed.data / "exostudy"
        assert {p.name: oct(stat.S_IMODE(p.stat().st_mode)) for p in data.glob("exostudy.db*")
                } == {"exostudy.db": "0o600", "exostudy.db-wal": "0o600",
                      "exostudy.db-shm": "0o600"}
        health = c.get("/api/health").json()
        assert health["version"] == installed.version
        # The worker runs from the wheel and the spawned UDP simulator sends samples.
        wait_for(lambda: c.get("/api/health").json()["device"]["alive"], 120,
                 "samples from the wheel's device simulator", poll=0.5)


@pytest.fixture(scope="module")
def virtual_study(installed: Installed) -> Path:
    """The smallest virtual study the command accepts, run from the wheel."""
    out = installed.cwd / "vs"
    installed.run("virtual-study", "--participants", "1", "--data-participants", "2",
                  "--eumc", "0", "--rates", "paper-rates", "--no-model-evaluation",
                  "--collection-speed", "400", "--out", str(out), timeout=900)
    return out


def test_a_small_virtual_study_from_the_wheel(installed: Installed, virtual_study: Path
                                              ) -> None:
    summary = json.loads((virtual_study / "summary.json").read_text())
    assert summary["exostudy_version"] == installed.version
    assert (virtual_study / "paper-rates" / "performance.md").is_file()
    # One evaluation participant, UMC and PEC: two trials, each with its ticks.
    assert len(summary["trials"]) == 2, summary["trials"]
    assert all(t["ticks"] > 0 for t in summary["trials"])


def test_results_export_and_cohort_from_the_wheel(installed: Installed, virtual_study: Path
                                                  ) -> None:
    version = installed.version
    db = str(virtual_study / "study.db")
    results = installed.cwd / "results"
    installed.run("results", "--study", "1", "--db", db, "--out", str(results),
                  "--no-timelines")
    assert json.loads((results / "results.json").read_text())["exostudy_version"] == version
    assert (results / "performance.md").is_file() and (results / "peak_torques.svg").is_file()
    bids = installed.cwd / "bids"
    installed.run("export", "--study", "1", "--bids", str(bids), "--db", db)
    described = json.loads((bids / "dataset_description.json").read_text())
    assert described["GeneratedBy"][0]["Version"] == version
    assert list(bids.glob("sub-*/ses-*/motion/*_motion.tsv"))
    cohort = installed.cwd / "cohort"
    # Two controllers, so that the paired rank test runs (its kernel, `COMPILED_HERE`).
    installed.run("cohort", "--participants", "2", "--controllers", "umc,pec", "--out",
                  str(cohort))
    # The rank test's kernel was compiled in the new environment and cached beside the
    # installed source (numba writes an index and the compiled code there).
    purelib = Path(subprocess.run(
        [str(installed.venv / "bin" / "python"), "-c",
         "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True, text=True, check=True).stdout.strip())
    cached = purelib / Path(COMPILED_HERE).parent / "__pycache__"
    assert list(cached.glob("cohort_stats.*.nbi")) and list(cached.glob("cohort_stats.*.nbc"))
    assert (cohort / "metrics.csv").is_file() and (cohort / "README.md").is_file()


def test_the_installed_python_path_holds_no_part_of_the_clone(installed: Installed) -> None:
    """Only the borrowed dependencies may lie under the clone (its .venv), never its code."""
    paths = json.loads(subprocess.run(
        [str(installed.venv / "bin" / "python"), "-c", "import json, sys; "
         "print(json.dumps(sys.path))"], cwd=installed.cwd, env=installed.env,
        capture_output=True, text=True, check=True).stdout)
    inside = [p for p in paths if p and Path(p).resolve().is_relative_to(ROOT)]
    assert all(Path(p).resolve().is_relative_to(Path(sys.prefix).resolve()) for p in inside), \
        inside
    assert not (installed.venv / "var").exists()
