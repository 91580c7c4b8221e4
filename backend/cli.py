"""`exostudy`: the command line.

    exostudy serve [--host H] [--port P]      start the server (worker included)
    exostudy db upgrade|downgrade|current     manage the database schema
    exostudy device-sim --port P ...          the simulated exoskeleton on the wire
    exostudy simulate --seed S --script NAME --out FILE.csv
    exostudy replay --angles IN.csv --controller umc ... --out TICKS.csv
    exostudy human-dataset --out FILE.json     the simulated reference human data
    exostudy user add NAME                     create an experimenter (password on stdin)
    exostudy user list                         list the experimenter accounts
    exostudy virtual-study --participants 8 --seed S --out DIR   the protocol, simulated
    exostudy results --study ID --out DIR [--db URL]   a study's tables and figures
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path


def _serve(args: argparse.Namespace) -> int:
    import uvicorn

    from backend.core.config import Settings
    from backend.main import create_app

    overrides: dict[str, object] = {}
    if args.host:
        overrides["host"] = args.host
    if args.port is not None:
        overrides["port"] = args.port
    settings = Settings(**overrides)  # type: ignore[arg-type]
    app = create_app(settings)
    print(f"ExoStudy is starting on http://{settings.host}:{settings.port}/", flush=True)
    # One process only: the worker and the 3D view are per server process.
    uvicorn.run(app, host=settings.host, port=settings.port, log_level=args.log_level, workers=1)
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

    from backend import accounts, audit
    from backend.core.config import Settings
    from backend.db import migrate
    from backend.db.engine import make_engine, make_session_factory
    from backend.db.models import User

    url = Settings().database_url
    migrate.upgrade(url)
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            if args.action == "list":
                for u in session.scalars(select(User).order_by(User.username)):
                    print(f"{u.username}\t{'active' if u.active else 'disabled'}")
                return 0
            if not args.name:
                raise ValueError("user add: give the NAME of the account")
            password = _read_password(sys.stdin.isatty())
            try:
                user = accounts.create_user(session, args.name, password)
            except accounts.AccountError as exc:
                raise ValueError(str(exc)) from exc
            audit.record(session, "command line", "create", "user", user.id,
                         {"username": user.username})
            session.commit()
            print(f"created experimenter {user.username!r}")
            return 0
    finally:
        engine.dispose()


def _virtual_study(args: argparse.Namespace) -> int:
    from backend.virtual_study import COLLECTION_SPEED, DEFAULT_SPEED, VirtualStudyConfig, run

    cfg = VirtualStudyConfig(
        out=Path(args.out), participants=args.participants,
        data_participants=args.data_participants, eumc=args.eumc, seed=args.seed,
        speed=args.speed if args.speed is not None else DEFAULT_SPEED,
        collection_speed=(args.collection_speed if args.collection_speed is not None
                          else COLLECTION_SPEED),
        rates=tuple(args.rates.split(",")), model_evaluation=not args.no_model_evaluation)
    report = run(cfg, log=lambda m: print(m, flush=True))
    print(f"virtual study done in {report.wall_s:.0f} s; {len(report.trials)} trials; "
          f"wrote {len(report.files)} files to {args.out} (see README.md there)")
    return 0


def _results(args: argparse.Namespace) -> int:
    from backend.core.config import Settings
    from backend.db import migrate
    from backend.db.engine import make_engine, make_session_factory
    from backend.results_files import write_study_results

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


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and documentation)."""
    p = argparse.ArgumentParser(prog="exostudy", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("serve", help="start the server")
    s.add_argument("--host", default=None)
    s.add_argument("--port", type=int, default=None)
    s.add_argument("--log-level", default="info")
    s.set_defaults(func=_serve)

    d = sub.add_parser("db", help="database schema migrations")
    d.add_argument("action", choices=["upgrade", "downgrade", "current"])
    d.add_argument("revision", nargs="?", default=None)
    d.set_defaults(func=_db)

    sub.add_parser("device-sim", help="run the simulated exoskeleton on the wire (UDP); "
                   "see `exostudy device-sim --help`")

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
                       "password from standard input; `user list`")
    u.add_argument("action", choices=["add", "list"])
    u.add_argument("name", nargs="?", default=None)
    u.set_defaults(func=_user)

    v = sub.add_parser("virtual-study", help="run the paper's protocol on virtual "
                       "participants through the server, worker and simulated device")
    v.add_argument("--participants", type=int, default=8, help="evaluation participants")
    v.add_argument("--data-participants", type=int, default=6,
                   help="data-collection participants whose demonstrations fit the models")
    v.add_argument("--eumc", type=int, default=3, help="the first N also evaluate the E-UMC")
    v.add_argument("--seed", type=int, default=1)
    v.add_argument("--speed", type=float, default=None,
                   help="simulator speed-up in the trials (default: "
                   "backend.virtual_study.DEFAULT_SPEED)")
    v.add_argument("--collection-speed", type=float, default=None,
                   help="simulator speed-up while demonstrations are recorded (default: "
                   "backend.virtual_study.COLLECTION_SPEED)")
    v.add_argument("--rates", default="paper-rates,100hz",
                   help="comma-separated rate settings: paper-rates, 100hz")
    v.add_argument("--no-model-evaluation", action="store_true",
                   help="skip the leave-one-participant-out evaluation of the models")
    v.add_argument("--out", required=True)
    v.set_defaults(func=_virtual_study)

    r = sub.add_parser("results", help="write a study's tables (CSV, Markdown), figures "
                       "(PNG, SVG) and trial timelines from an existing database")
    r.add_argument("--study", type=int, required=True, help="the study's id")
    r.add_argument("--out", required=True, help="folder to write into")
    r.add_argument("--db", default=None, help="SQLite file or database URL (default: "
                   "EXOSTUDY_DATABASE_URL, i.e. the server's database)")
    r.add_argument("--no-timelines", action="store_true",
                   help="skip the per-trial five-panel figures")
    r.set_defaults(func=_results)

    sub.add_parser("replay", help="replay recorded angles through a controller; "
                   "see `exostudy replay --help`")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `exostudy` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    # Subcommands with their own parsers get their arguments untouched.
    passthrough = {"replay": "controller.replay", "device-sim": "controller.sim.device_server"}
    if argv and argv[0] in passthrough:
        import importlib

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
