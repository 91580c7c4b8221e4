"""The application factory: settings -> migrated database -> live path -> routes -> pages."""

from __future__ import annotations

import asyncio
import functools
import ipaddress
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import APIRouter, Depends, FastAPI
from fastapi.responses import RedirectResponse
from fastapi.staticfiles import StaticFiles
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from backend import console_pages
from backend.analysis import jobs
from backend.api import docs_assets, guide, json_text, log_redaction, viewer, web_surface
from backend.api.deps import authorize, document_access, heavy_reads_gate
from backend.api.errors import install_handlers
from backend.api.openapi import api_routes, document_framework_errors, name_operations
from backend.api.routes import (
    audit,
    auth,
    cohorts,
    device_grants,
    emg,
    hardware,
    health,
    lab,
    live,
    model_sets,
    participant_forms,
    participants,
    personalisation,
    preferences,
    questionnaires,
    recordings,
    replication,
    results,
    sessions,
    studies,
    trial_segments,
    trials,
    vocabulary,
    wearers,
    worker,
)
from backend.api.socket_logins import SocketLogins
from backend.core import data_folder
from backend.core.config import Settings, get_settings
from backend.core.resources import version
from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.emg import recovery as emg_recovery
from backend.emg import store as emg_store
from backend.emg.live import EmgLab
from backend.lab.hub import Lab
from backend.live.parts import StudyHooks
from backend.live.runtime import Runtime
from backend.questionnaires.catalog import ensure_built_ins
from backend.study import accounts, activity, demo

log = logging.getLogger(__name__)


def refuse_published_passwords(settings: Settings, sessions: sessionmaker[Session]) -> None:
    """Refuse to serve beyond this machine while an account has a published password
    (the demo's, printed in the README): anyone on the network could log in."""
    with sessions() as db:
        names = accounts.published_password_accounts(db)
    if not names:
        return
    host = settings.host.strip("[]")
    try:
        loopback = ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = host == "localhost"
    if not loopback:
        raise RuntimeError(
            f"refusing to listen on {settings.host}: account(s) {', '.join(names)} still "
            "have the published demo password; change it (`exostudy user passwd NAME`) "
            "or disable the account (`exostudy user disable NAME`) first")
    log.warning("account(s) %s still have the published demo password: change it before "
                "serving beyond this machine", ", ".join(names))


def attach_to_live_path(app: FastAPI, runtime: Runtime, settings: Settings,
                        engine: Engine) -> None:
    """Give the live path what sits above it, so that it imports none of it: the lab's
    LSL streams and markers (fed every tick batch), the EMG inlets (both started and
    stopped with it) and the study's running trials and recordings (closed as
    interrupted when the worker dies). Routes reach the lab and the EMG inlets through
    `app.state` (`deps.LabDep`, `deps.EmgLabDep`)."""
    broadcast = runtime.stream.broadcast_json
    lab_hub = Lab(settings.lsl_enabled, settings.lsl_name, engine, broadcast)
    emg_inlets = EmgLab(settings.lsl_enabled, engine, settings, publish=broadcast)
    runtime.parts += [lab_hub, emg_inlets]
    runtime.listeners.append(lab_hub)
    app.state.lab, app.state.emg = lab_hub, emg_inlets
    sessions: sessionmaker[Session] = app.state.sessions

    def running() -> str | None:
        with sessions() as db:
            return activity.running(db)

    runtime.study = StudyHooks(
        running=running,
        interrupt_running=lambda reason: activity.interrupt_running(engine, reason))


def create_demo(runtime: Runtime, settings: Settings, sessions: sessionmaker[Session]) -> None:
    """The demo study in an empty database, from the default sets the live path built
    (when the demo is on)."""
    if settings.demo and runtime.defaults is not None:
        with sessions() as db:
            demo.ensure_demo(db, *runtime.defaults, settings.precompression_pct)


#: Every router of the app, included without a prefix, in matching order.
ROUTERS: tuple[APIRouter, ...] = (
    health.router, worker.router, hardware.router, live.router, auth.router,
    auth.users, studies.router, participants.router, sessions.router,
    questionnaires.router, preferences.router, participant_forms.router,
    participant_forms.pages, audit.router, recordings.router, model_sets.router,
    personalisation.router, trials.router, trial_segments.router, lab.router,
    emg.router, results.router, wearers.router, cohorts.router, replication.router,
    vocabulary.router, device_grants.router, console_pages.router, guide.router,
    viewer.router,
)


@functools.cache
def included_routers() -> APIRouter:
    """`ROUTERS` included once per process, for every app it builds.

    FastAPI (0.16x) builds an included route's context (its dependencies, request and
    response models, validators) the first time a request or the schema walks it, and
    keeps it in the inclusion: about 0.1 s of CPU per router, paid again by every new app
    that includes the routers itself. A process builds many apps only in tests (one per
    test, hundreds per run), but the built contexts hold nothing of an app: the access
    check is the same function for all (`authorize`, as the app's own dependency), and
    the request's app is reached through the request. One difference from
    `app.include_router`: `app.dependency_overrides` does not reach these routes (their
    inclusion belongs to no app); nothing here overrides dependencies."""
    parent = APIRouter(dependencies=[Depends(authorize)])
    for router in ROUTERS:
        parent.include_router(router)
    return parent


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app. Migrations are applied at start-up, so a fresh clone just works."""
    settings = settings or get_settings()

    log_redaction.install()  # participant link tokens never in full in a log

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        log_redaction.install()  # again: uvicorn may have set up logging since
        # Private before anything is written: folder 0700, database and key files 0600.
        tightened = data_folder.make_private(settings)
        if tightened:
            log.warning("made private (group and others had access): %s",
                        "; ".join(tightened))
        for exposed in data_folder.exposures(settings).lines():
            log.warning("data readable by others: %s", exposed)
        migrate.upgrade(settings.database_url)
        engine = make_engine(settings.database_url)
        app.state.settings = settings
        app.state.engine = engine
        app.state.sessions = make_session_factory(engine)
        with app.state.sessions() as db:
            ensure_built_ins(db)
        # What a killed server left running ends as interrupted, with its tick counts,
        # before a new worker could attach anything to it.
        closed = activity.recover(engine)
        if closed:
            log.warning("closed after an unclean stop: %s", ", ".join(closed))
        # Background jobs a previous process left queued or running end failed, and so
        # do the sets and cohorts they were producing (backend/analysis/jobs.py).
        interrupted = jobs.recover(app.state.sessions)
        if interrupted:
            log.warning("interrupted by the restart: %s", ", ".join(interrupted))
        # EMG recordings a killed server was writing keep what their .part holds.
        with app.state.sessions() as db:
            for line in emg_recovery.recover(db, emg_store.emg_folder(settings)):
                log.warning("interrupted by the restart: %s", line)
        # The tick writer has an engine (a pool) of its own: no number of API reads
        # holding the app's connections can keep a running trial's ticks from the disk.
        writer_engine = make_engine(settings.database_url)
        runtime = Runtime(settings, writer_engine)
        attach_to_live_path(app, runtime, settings, engine)
        app.state.runtime = runtime
        app.state.jobs = jobs.JobRunner(app.state.sessions)
        await runtime.start()
        try:
            await asyncio.to_thread(create_demo, runtime, settings, app.state.sessions)
            refuse_published_passwords(settings, app.state.sessions)
            yield
        finally:
            app.state.jobs.begin_shutdown()  # jobs stop while the worker stops
            await runtime.stop()
            app.state.jobs.shutdown()
            writer_engine.dispose()
            engine.dispose()

    app = FastAPI(
        title="ExoStudy",
        version=version(),
        summary="Intent estimation and decision-theoretic control for a quasi-passive hip "
        "exoskeleton, and the studies around it.",
        lifespan=lifespan,
        # The one access check of every route, present and future (backend/api/deps.py).
        dependencies=[Depends(authorize)],
        # /docs is served from local assets below (no CDN): studies run offline.
        docs_url=None,
        redoc_url=None,
    )
    # Inside the body limit (middleware added later wraps the earlier ones).
    app.add_middleware(json_text.StorableJsonText)
    # WebSockets end with their login: revoking routes wake their watchers.
    app.state.socket_logins = SocketLogins()
    # Reads of ticks beside a request's session, a few at a time (backend/api/deps.py).
    app.state.heavy_reads = heavy_reads_gate()
    # Routes that take a file allow max_upload_bytes, all others max_body_bytes; the
    # list is filled below, once the routes are included.
    upload_paths: list[str] = []
    app.add_middleware(web_surface.BodyLimit, limit=settings.max_body_bytes,
                       upload_limit=settings.max_upload_bytes, upload_paths=upload_paths)
    app.add_middleware(web_surface.SecurityHeaders)
    docs_assets.install(app, settings.frontend_dir)
    install_handlers(app)
    app.router.routes.extend(included_routers().routes)
    document_framework_errors(app)
    document_access(app)
    name_operations(app, ROUTERS)  # operationIds: the console client's names
    upload_paths.extend(web_surface.file_routes(api_routes(app, ROUTERS)))

    static = settings.frontend_dir / "static"
    uplot = settings.frontend_dir / "node_modules" / "uplot" / "dist"
    if not uplot.is_dir():
        log.warning("uPlot not found at %s: run `make run` (npm ci) to install it", uplot)
    else:
        app.mount("/vendor/uplot", StaticFiles(directory=uplot), name="uplot")
    app.mount("/static", StaticFiles(directory=static), name="static")

    @app.get("/", include_in_schema=False)
    def index() -> RedirectResponse:
        return RedirectResponse("/live")

    return app
