"""`exostudy`: the command line.

    exostudy serve [--host H] [--port P]      start the server (worker included)
    exostudy db upgrade|downgrade|current     manage the database schema
    exostudy doctor                           what in the data folder others can read
    exostudy device-sim --port P ...          the simulated exoskeleton on the wire
    exostudy simulate --seed S --script NAME --out FILE.csv
    exostudy replay --angles IN.csv --controller umc ... --out TICKS.csv
    exostudy human-dataset --out FILE.json     the simulated reference human data
    exostudy user add NAME [--admin]           create an account (password on stdin)
    exostudy user passwd|disable|enable NAME   new password (stdin) / turn an account off/on
    exostudy user list                         list the accounts, their role and state
    exostudy user grant-device|revoke-device NAME  give/take the lab's device grant
    exostudy virtual-study --participants 8 --seed S --out DIR   the protocol, simulated
    exostudy cohort --participants N --seed S --out DIR   power and sample size, simulated
    exostudy personalisation --participants N --out DIR   personal models, learned priors
    exostudy emg-sweep --participants N --out DIR   spring settings vs muscle activity (prediction)
    exostudy results --study ID --out DIR [--db URL]   a study's tables and figures
    exostudy export --study ID --bids DIR [--db URL]   a study as a BIDS-motion dataset
    exostudy replicate --out DIR [--seeds N] [--from-db PATHS...]   the paper, claim by claim
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from controller.help_format import DefaultsHelpFormatter

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from backend.core.config import Settings


def _serve(args: argparse.Namespace) -> int:
    import uvicorn

    from backend.core.config import Settings
    from backend.core.starting import ASGIApp, StagedApp

    overrides: dict[str, object] = {}
    if args.host:
        overrides["host"] = args.host
    if args.port is not None:
        overrides["port"] = args.port
    settings = Settings(**overrides)  # type: ignore[arg-type]
    failures: list[str] = []

    def load() -> ASGIApp:
        from backend.main import create_app

        return create_app(settings)

    def failed(message: str) -> None:
        failures.append(message)
        server.should_exit = True

    # Listens at once and answers "starting" (503) while the application loads and
    # starts in the background (backend/core/starting.py).
    app = StagedApp(load, failed)
    print(f"ExoStudy is starting on http://{settings.host}:{settings.port}/", flush=True)
    # One process only: the worker and the 3D view are per server process.
    server = uvicorn.Server(uvicorn.Config(app, host=settings.host, port=settings.port,
                                           log_level=args.log_level, workers=1,
                                           lifespan="on"))
    server.run()
    if failures:
        print(f"ExoStudy did not start: {failures[0]}", file=sys.stderr, flush=True)
        return 1
    return 0


def _db(args: argparse.Namespace) -> int:
    from backend.core.config import Settings
    from backend.db import migrate

    url = Settings().database_url
    if args.action == "upgrade":
        migrate.upgrade(url, args.revision or "head")
        print(f"database at revision {migrate.current(url)}: {url}")
    elif args.action == "downgrade":
        migrate.downgrade(url, args.revision or "base")
        print(f"database at revision {migrate.current(url)}: {url}")
    else:
        print(migrate.current(url) or "empty")
    return 0


def _emg_orphans(settings: Settings) -> list[Path]:
    """EMG files no recording row claims (none when the database cannot be read)."""
    from sqlalchemy.exc import SQLAlchemyError

    from backend.db.engine import make_engine, make_session_factory
    from backend.emg import recovery, store

    try:
        engine = make_engine(settings.database_url)
        try:
            with make_session_factory(engine)() as db:
                return recovery.orphans(db, store.emg_folder(settings))
        finally:
            engine.dispose()
    except SQLAlchemyError:
        return []


def _doctor(args: argparse.Namespace) -> int:
    """Exit status 1 while a folder or file of the data is open to other accounts."""
    from backend.core import data_folder
    from backend.core.config import Settings

    settings = Settings()
    found = data_folder.exposures(settings)
    for line in found.lines():
        print(f"warning: {line}")
    folders = ", ".join(str(f) for f in data_folder.own_folders(settings))
    orphans = _emg_orphans(settings)
    for path in orphans:
        print(f"warning: EMG file {path} belongs to no recording (an erasure whose "
              "deletion failed, or a file set aside): delete it once checked")
    if orphans and not found.count:
        return 1
    if not found.count:
        print(f"ok: the data ({folders}) is readable by its owner only"
              + (" (as far as it was looked at)" if found.walk_stopped else ""))
        return 0
    print(f"{found.count} path(s) open to others; `exostudy serve` makes the data folder "
          f"({folders}), what is directly in it and the database private at start; "
          "deeper paths need the `chmod` shown")
    return 1


def _simulate(args: argparse.Namespace) -> int:
    from controller.sim.recording import simulate_to_csv

    n = simulate_to_csv(args.seed, args.script, Path(args.out))
    print(f"wrote {n} samples to {args.out}")
    return 0


def _human_dataset(args: argparse.Namespace) -> int:
    from controller.sim.human_dataset import write_reference_dataset

    data = write_reference_dataset(Path(args.out), seed=args.seed)
    print(f"wrote reference human dataset {data.version} to {args.out}")
    return 0


def _read_password(prompt_twice: bool) -> str:
    """The password from standard input: asked twice at a terminal, else the first line
    (so `printf '%s\n' "$PW" | exostudy user add NAME` works in scripts)."""
    if prompt_twice:
        import getpass

        first = getpass.getpass("password: ")
        if getpass.getpass("again: ") != first:
            raise ValueError("password: the two entries differ")
        return first
    return sys.stdin.readline().rstrip("\r\n")


def _user(args: argparse.Namespace) -> int:
    from sqlalchemy import select

    from backend.core.config import Settings
    from backend.db import audit, migrate
    from backend.db.engine import make_engine, make_session_factory
    from backend.db.models import User
    from backend.study import accounts

    url = Settings().database_url
    migrate.upgrade(url)
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            if args.action == "list":
                for u in session.scalars(select(User).order_by(User.username)):
                    print(f"{u.username}\t{u.role}\t{'active' if u.active else 'disabled'}")
                return 0
            if not args.name:
                raise ValueError(f"user {args.action}: give the NAME of the account")
            if args.action != "add":
                found = session.scalars(select(User).where(User.username == args.name)).first()
                if found is None:
                    raise ValueError(f"user {args.action}: no account named {args.name!r}")
                if args.action in ("grant-device", "revoke-device"):
                    return _device_grant(session, args.action, found.username)
                try:
                    if args.action == "passwd":
                        accounts.change_password(session, found, _read_password(
                            sys.stdin.isatty()))
                        accounts.revoke_all(session, found)
                    else:
                        accounts.set_active(session, found, args.action == "enable")
                except accounts.AccountError as exc:
                    raise ValueError(str(exc)) from exc
                audit.record(session, "command line", args.action, "user", found.id,
                             {"username": found.username})
                session.commit()
                print(f"{args.action}: done for {found.username!r}")
                return 0
            password = _read_password(sys.stdin.isatty())
            try:
                user = accounts.create_user(session, args.name, password,
                                            "admin" if args.admin else None)
            except accounts.AccountError as exc:
                raise ValueError(str(exc)) from exc
            audit.record(session, "command line", "create", "user", user.id,
                         {"username": user.username})
            session.commit()
            print(f"created experimenter {user.username!r}")
            return 0
    finally:
        engine.dispose()


def _device_grant(session: Session, action: str, username: str) -> int:
    """`user grant-device|revoke-device NAME` (backend/study/device_grants.py)."""
    from backend.study import device_grants

    if action == "grant-device":
        device_grants.grant(session, "command line", username)
        print(f"grant-device: {username!r} may use the exoskeleton")
    elif device_grants.revoke(session, "command line", username):
        print(f"revoke-device: {username!r} may no longer use the exoskeleton")
    else:
        print(f"revoke-device: {username!r} held no device grant")
    return 0


def _virtual_study(args: argparse.Namespace) -> int:
    from backend.analysis.virtual_study import VirtualStudyConfig, run

    cfg = VirtualStudyConfig(
        out=Path(args.out), participants=args.participants,
        data_participants=args.data_participants, eumc=args.eumc, seed=args.seed,
        speed=args.speed, collection_speed=args.collection_speed,
        rates=tuple(args.rates.split(",")), model_evaluation=not args.no_model_evaluation,
        emg=args.emg)
    report = run(cfg, log=lambda m: print(m, flush=True))
    print(f"virtual study done in {report.wall_s:.0f} s; {len(report.trials)} trials; "
          f"wrote {len(report.files)} files to {args.out} (see README.md there)")
    return 0


def _cohort(args: argparse.Namespace) -> int:
    import time

    from controller.decision.utility_function import UtilitySet
    from controller.evaluation.cohort import CohortConfig, auto_processes, simulate_cohort
    from controller.evaluation.cohort_report import analyse, write_outputs
    from controller.intent.motion_model import ModelSet

    cfg = CohortConfig(participants=args.participants, seed=args.seed,
                       controllers=tuple(c.strip() for c in args.controllers.split(",")
                                         if c.strip()),
                       rate_hz=args.rate, emg=args.emg)
    from backend import bootstrap
    from backend.core.config import Settings

    t0 = time.monotonic()
    if args.processes < 0:
        raise ValueError("--processes: at least 1, or 0 for one per core")
    # Without files named, the server's default sets (as its cohort jobs use them): fitted
    # from the simulated data collection once and kept in the data folder, not refitted
    # per cohort (that took a third of a 100-participant cohort's time).
    server = Settings()
    models = (ModelSet.load(Path(args.models)) if args.models
              else bootstrap.ensure_models(server.models_path))
    utilities = (UtilitySet.load(Path(args.utilities)) if args.utilities
                 else bootstrap.ensure_utilities(
                     bootstrap.utilities_path(server.utilities_dir, cfg.precompression_pct),
                     cfg.precompression_pct))
    cohort = simulate_cohort(cfg, models, utilities,
                             processes=args.processes or auto_processes(cfg.participants))
    t1 = time.monotonic()
    paths = write_outputs(cohort, analyse(cohort, seed=args.seed), Path(args.out))
    print(f"cohort of {cfg.participants} simulated in {t1 - t0:.1f} s, statistics and files "
          f"in {time.monotonic() - t1:.1f} s; wrote {len(paths)} files to {args.out} "
          "(see README.md there)")
    return 0


def _floats(text: str, what: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ValueError(f"{what}: comma-separated numbers, got {text!r}") from None


def _emg_sweep(args: argparse.Namespace) -> int:
    import time

    from controller.evaluation.emg_sweep import SweepConfig, run_sweep, write_outputs
    from controller.intent.motion_model import ModelSet

    cfg = SweepConfig(participants=args.participants, seed=args.seed,
                      controllers=tuple(c.strip() for c in args.controllers.split(",")
                                        if c.strip()),
                      precompressions=_floats(args.precompressions, "--precompressions"),
                      stiffness_factors=_floats(args.stiffness, "--stiffness"))
    models = ModelSet.load(Path(args.models)) if args.models else None
    t0 = time.monotonic()
    rows = run_sweep(cfg, models, log=lambda m: print(m, flush=True))
    wall = time.monotonic() - t0
    paths = write_outputs(cfg, rows, Path(args.out), wall)
    print(f"sweep of {len(rows)} settings x controllers in {wall:.0f} s; wrote {len(paths)} "
          f"files to {args.out} (a model prediction; see README.md there)")
    return 0


def _results(args: argparse.Namespace) -> int:
    from backend.analysis.results_files import write_study_results
    from backend.core.config import Settings
    from backend.db import migrate
    from backend.db.engine import make_engine, make_session_factory

    url = args.db or Settings().database_url
    if "://" not in url:
        if not Path(url).is_file():
            raise FileNotFoundError(f"--db: no database file at {url}")
        url = f"sqlite:///{Path(url).resolve()}"
    elif url.startswith("sqlite:///") and not Path(url[len("sqlite:///"):]).is_file():
        raise FileNotFoundError(f"--db: no database file at {url[len('sqlite:///'):]}")
    if migrate.current(url) is None:
        raise ValueError(f"--db: {url} is not an ExoStudy database (no schema revision)")
    migrate.upgrade(url)  # as the server does at start: an older file gains new columns
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as db:
            paths = write_study_results(engine, db, args.study, Path(args.out),
                                        timelines=not args.no_timelines)
    finally:
        engine.dispose()
    print(f"wrote {len(paths)} files for study {args.study} to {args.out}")
    return 0


def _export(args: argparse.Namespace) -> int:
    from backend.core.config import Settings
    from backend.db import migrate
    from backend.db.engine import make_engine, make_session_factory
    from backend.lab.bids_export import dataset_files
    from controller.private_files import make_private_dir, write_private

    url = args.db or Settings().database_url
    if "://" not in url:
        if not Path(url).is_file():
            raise FileNotFoundError(f"--db: no database file at {url}")
        url = f"sqlite:///{Path(url).resolve()}"
    if migrate.current(url) is None:
        raise ValueError(f"--db: {url} is not an ExoStudy database (no schema revision)")
    migrate.upgrade(url)
    out = Path(args.bids)
    if out.exists() and any(out.iterdir()):
        raise ValueError(f"--bids: {out} is not empty; give a new or empty folder")
    engine = make_engine(url)
    n = 0
    try:
        with make_session_factory(engine)() as db:
            # Participants' data: folders 0700 and files 0600, whatever the umask.
            for rel, data in dataset_files(engine, db, args.study, unblind=not args.blind):
                path = out / rel
                make_private_dir(path.parent)
                write_private(path, data)
                n += 1
    finally:
        engine.dispose()
    print(f"wrote a BIDS dataset of {n} files for study {args.study} to {out}")
    return 0


def _replicate(args: argparse.Namespace) -> int:
    from backend.analysis.replication_config import DEFAULT_PERSONALISATION, ReplicationConfig
    from backend.analysis.replication_run import run
    from controller.evaluation.paper_claims import DEFAULT_SEEDS

    cfg = ReplicationConfig(
        out=Path(args.out), seeds=DEFAULT_SEEDS if args.seeds is None else args.seeds,
        first_seed=args.first_seed, engine=args.engine,
        from_db=tuple(Path(p) for p in args.from_db or ()), participants=args.participants,
        eumc=args.eumc, data_participants=args.data_participants,
        offset_participants=args.offset_participants,
        stair_participants=args.stair_participants,
        personalisation_participants=DEFAULT_PERSONALISATION
        if args.personalisation_participants is None else args.personalisation_participants)
    rep = run(cfg, log=lambda m: print(m, flush=True))
    print(f"replication done in {rep.wall_s:.0f} s: {args.out}/report.html")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and documentation)."""
    p = argparse.ArgumentParser(prog="exostudy", description=__doc__,
                                formatter_class=DefaultsHelpFormatter)
    from backend.analysis.virtual_study_speeds import COLLECTION_SPEED, DEFAULT_SPEED
    from backend.core.config import Settings
    from backend.core.resources import version

    p.add_argument("--version", action="version", version=f"exostudy {version()}")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("serve", help="start the server")
    server = Settings.model_fields
    s.add_argument("--host", default=None, help="address to listen on (default: "
                   f"EXOSTUDY_HOST, else {server['host'].default})")
    s.add_argument("--port", type=int, default=None, help="TCP port (default: "
                   f"EXOSTUDY_PORT, else {server['port'].default})")
    s.add_argument("--log-level", default="info", help="uvicorn's log level")
    s.set_defaults(func=_serve)

    d = sub.add_parser("db", help="database schema migrations")
    d.add_argument("action", choices=["upgrade", "downgrade", "current"])
    d.add_argument("revision", nargs="?", default=None,
                   help="target revision (default: head to upgrade, base to downgrade)")
    d.set_defaults(func=_db)

    dr = sub.add_parser("doctor", help="warn about data that other accounts on this "
                        "machine can read: the data folder, the database and its WAL "
                        "files, the device key (exit status 1 if any)")
    dr.set_defaults(func=_doctor)

    sub.add_parser("device-sim", help="run the simulated exoskeleton on the wire (UDP); "
                   "see `exostudy device-sim --help`; `--implementation c` runs the C "
                   "firmware core instead (firmware/build/exostudy-device)")

    sim = sub.add_parser("simulate", help="write a simulated recording as CSV")
    sim.add_argument("--seed", type=int, required=True)
    sim.add_argument("--script", required=True)
    sim.add_argument("--out", required=True)
    sim.set_defaults(func=_simulate)

    h = sub.add_parser("human-dataset", help="regenerate the simulated reference human "
                       "motion dataset (angles and torques per motion and leg) as JSON")
    h.add_argument("--out", required=True)
    h.add_argument("--seed", type=int, default=0)
    h.set_defaults(func=_human_dataset)

    u = sub.add_parser("user", help="experimenter accounts: `user add NAME` reads the "
                       "password from standard input; `user passwd NAME`, `user disable NAME`, "
                       "`user enable NAME`, `user list`, `user grant-device NAME` (the "
                       "lab's right to use the exoskeleton), `user revoke-device NAME`")
    u.add_argument("action", choices=["add", "list", "passwd", "disable", "enable",
                                      "grant-device", "revoke-device"])
    u.add_argument("name", nargs="?", default=None)
    u.add_argument("--admin", action="store_true",
                   help="with add: an administrator (the first account always is)")
    u.set_defaults(func=_user)

    v = sub.add_parser("virtual-study", help="run the paper's protocol on virtual "
                       "participants through the server, worker and simulated device")
    v.add_argument("--participants", type=int, default=8, help="evaluation participants")
    v.add_argument("--data-participants", type=int, default=6,
                   help="data-collection participants whose demonstrations fit the models")
    v.add_argument("--eumc", type=int, default=3, help="the first N also evaluate the E-UMC")
    v.add_argument("--seed", type=int, default=1, help="seed of the virtual participants")
    v.add_argument("--speed", type=float, default=DEFAULT_SPEED,
                   help="simulator speed-up in the trials (the simulator's maximum)")
    v.add_argument("--collection-speed", type=float, default=COLLECTION_SPEED,
                   help="simulator speed-up while demonstrations are recorded")
    v.add_argument("--rates", default="paper-rates,100hz",
                   help="comma-separated rate settings: paper-rates, 100hz")
    v.add_argument("--emg", action="store_true",
                   help="also the two baseline conditions and the simulated wearer's EMG, "
                        "recorded over LSL, with the muscle-activity results (slower); "
                        "without it, the paper's protocol alone")
    v.add_argument("--no-model-evaluation", action="store_true",
                   help="skip the leave-one-participant-out evaluation of the models")
    v.add_argument("--out", required=True)
    v.set_defaults(func=_virtual_study)

    c = sub.add_parser("cohort", help="simulate N virtual participants through the "
                       "controllers (batch replay) and compute confidence intervals, paired "
                       "tests and power curves")
    c.add_argument("--participants", type=int, default=100)
    c.add_argument("--seed", type=int, default=1)
    c.add_argument("--controllers", default="umc,eumc,pec",
                   help="comma-separated: umc, eumc, pec")
    c.add_argument("--rate", type=float, default=None,
                   help="every controller at this rate (Hz); default: the paper's rates")
    c.add_argument("--models", default=None, help="model set JSON (default: the server's "
                   "default set, fitted once from the simulated data collection and kept "
                   "in the data folder)")
    c.add_argument("--utilities", default=None, help="utility set JSON (default: the "
                   "server's default set, from the simulated reference human dataset)")
    c.add_argument("--processes", type=int, default=0,
                   help="spread the participants over this many processes; 0: one per "
                   "core, at most one per 20 participants (the workers are forked with "
                   "the compiled kernels loaded, so they start at once) (default 0)")
    c.add_argument("--emg", action="store_true",
                   help="also simulate muscle activity: sEMG of every lift trial, an MVC, "
                   "and the baseline conditions springs_free and no_exoskeleton (about "
                   "0.6 s per trial more; docs/muscle-activity.md)")
    c.add_argument("--out", required=True)
    c.set_defaults(func=_cohort)

    from backend import personalisation_cli

    personalisation_cli.add_parser(sub)

    w = sub.add_parser("emg-sweep", help="predict, over spring precompression and "
                       "stiffness, each controller's peak support torque and reduction of "
                       "muscle activation on a virtual cohort (a model prediction)")
    w.add_argument("--participants", type=int, default=10)
    w.add_argument("--seed", type=int, default=1)
    w.add_argument("--controllers", default="umc,eumc,pec",
                   help="comma-separated: umc, eumc, pec")
    w.add_argument("--precompressions", default="0,10,25,50",
                   help="comma-separated precompressions, %% of the 22 mm spring travel")
    w.add_argument("--stiffness", default="0.5,1,1.5,2",
                   help="comma-separated spring stiffness as factors of the prototype's "
                   "2 x 33.6 N/mm")
    w.add_argument("--models", default=None, help="model set JSON (default: fitted from the "
                   "simulated data collection)")
    w.add_argument("--out", required=True)
    w.set_defaults(func=_emg_sweep)

    r = sub.add_parser("results", help="write a study's tables (CSV, Markdown), figures "
                       "(PNG, SVG) and trial timelines from an existing database")
    r.add_argument("--study", type=int, required=True, help="the study's id")
    r.add_argument("--out", required=True, help="folder to write into")
    r.add_argument("--db", default=None, help="SQLite file or database URL (default: "
                   "EXOSTUDY_DATABASE_URL, i.e. the server's database)")
    r.add_argument("--no-timelines", action="store_true",
                   help="skip the per-trial five-panel figures")
    r.set_defaults(func=_results)

    e = sub.add_parser("export", help="write a study as a BIDS-motion dataset")
    e.add_argument("--study", type=int, required=True, help="the study's id")
    e.add_argument("--bids", required=True, help="a new or empty folder to write into")
    e.add_argument("--blind", action="store_true",
                   help="leave the blinding key out, as in an experimenter's download: "
                   "files named by blinded label, no controller column")
    e.add_argument("--db", default=None, help="SQLite file or database URL (default: "
                   "EXOSTUDY_DATABASE_URL, i.e. the server's database)")
    e.set_defaults(func=_export)

    rp = sub.add_parser("replicate", help="the paper's claims one by one over several "
                        "virtual studies: an HTML report with figures (docs/replication.md)")
    rp.add_argument("--out", required=True, help="folder for the report and the seeds")
    rp.add_argument("--seeds", type=int, default=None,
                    help="virtual studies (default 20: DEFAULT_SEEDS of "
                    "controller.evaluation.paper_claims)")
    rp.add_argument("--first-seed", type=int, default=1)
    rp.add_argument("--engine", choices=["study", "cohort"], default="cohort",
                    help="cohort (the default): the paper's protocol replayed in this "
                    "process through the controllers' live tick code, minutes for 20 "
                    "seeds; study: the whole live virtual study (server, worker, "
                    "simulated device) per seed, reused when finished, about 100 minutes "
                    "for 20 seeds")
    rp.add_argument("--from-db", nargs="+", default=None,
                    help="read these study.db files instead of running seeds")
    rp.add_argument("--participants", type=int, default=8)
    rp.add_argument("--eumc", type=int, default=3)
    rp.add_argument("--data-participants", type=int, default=6)
    rp.add_argument("--offset-participants", type=int, default=60,
                    help="virtual cohort for the donning-offset regression")
    rp.add_argument("--stair-participants", type=int, default=20)
    rp.add_argument("--personalisation-participants", type=int, default=None,
                    help="virtual participants of the personalisation section (beyond the "
                    "paper; one cohort; default 40: DEFAULT_PERSONALISATION of "
                    "backend.analysis.replication_config, about 2.5 min measured here; 0 "
                    "leaves the section out)")
    rp.set_defaults(func=_replicate)

    sub.add_parser("hardware", help="hardware bring-up through the running server's API: "
                   "zero, direction, offset, pulse, watchdog, link, profile, status "
                   "(`exostudy hardware --help`)")
    sub.add_parser("replay", help="replay recorded angles through a controller; "
                   "see `exostudy replay --help`")
    # Every subcommand's help shows default values (not the names they come from).
    for parser in sub.choices.values():
        parser.formatter_class = DefaultsHelpFormatter
    return p


def _device_implementation(argv: list[str]) -> tuple[str, list[str]]:
    """`--implementation python|c` taken out of a device-sim command line (default:
    `python`); the rest goes to the device unchanged."""
    out: list[str] = []
    implementation = "python"
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--implementation" and i + 1 < len(argv):
            implementation = argv[i + 1]
            i += 2
            continue
        if arg.startswith("--implementation="):
            implementation = arg.split("=", 1)[1]
        else:
            out.append(arg)
        i += 1
    return implementation, out


def _exec_c_device(implementation: str, args: list[str]) -> int:
    """`exostudy device-sim --implementation c ARGS`: become the C device (same pid, so
    the server's bookkeeping and signals reach it), its wearer on this interpreter."""
    import os

    from backend.live.device_process import DeviceStartError, device_command

    try:
        command = device_command(args, implementation)
    except DeviceStartError as exc:
        print(f"exostudy device-sim: error: {exc}", file=sys.stderr)
        return 2
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(command[0], command)
    return 0  # not reached


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `exostudy` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    # Subcommands with their own parsers get their arguments untouched.
    passthrough = {"replay": "controller.runner.replay",
                   "device-sim": "controller.sim.device_server",
                   "hardware": "backend.hardware_cli"}
    if argv and argv[0] in passthrough:
        import importlib

        if argv[0] == "device-sim":
            from backend.live.device_process import die_with_parent

            die_with_parent()  # a server-spawned simulator never outlives its server
            implementation, argv = _device_implementation(argv)
            if implementation != "python":
                return _exec_c_device(implementation, argv[1:])
        module = importlib.import_module(passthrough[argv[0]])
        code: int = module.main(argv[1:])
        return code
    args = build_parser().parse_args(argv)
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"exostudy {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
