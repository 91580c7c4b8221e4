"""The application factory: settings -> migrated database -> live path -> routes -> pages."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.responses import FileResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles

from backend import console_pages, viewer
from backend.api.deps import SESSION_COOKIE, login_from_token
from backend.api.openapi import document_framework_errors
from backend.api.routes import (
    audit,
    auth,
    health,
    live,
    model_sets,
    participant_forms,
    participants,
    preferences,
    questionnaires,
    recordings,
    results,
    sessions,
    studies,
    trial_segments,
    trials,
    worker,
)
from backend.core.config import Settings, get_settings
from backend.db import migrate
from backend.db.engine import make_engine, make_session_factory
from backend.jobs import JobRunner
from backend.questionnaires.catalog import ensure_built_ins
from backend.runtime import Runtime

log = logging.getLogger(__name__)


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app. Migrations are applied at start-up, so a fresh clone just works."""
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        migrate.upgrade(settings.database_url)
        engine = make_engine(settings.database_url)
        app.state.settings = settings
        app.state.engine = engine
        app.state.sessions = make_session_factory(engine)
        with app.state.sessions() as db:
            ensure_built_ins(db)
        runtime = Runtime(settings, engine)
        app.state.runtime = runtime
        app.state.jobs = JobRunner(app.state.sessions)
        await runtime.start()
        try:
            yield
        finally:
            await runtime.stop()
            app.state.jobs.shutdown()
            engine.dispose()

    app = FastAPI(
        title="ExoStudy",
        version="0.1.0",
        summary="Intent estimation and decision-theoretic control for a quasi-passive hip "
        "exoskeleton, and the studies around it.",
        lifespan=lifespan,
    )
    app.include_router(health.router)
    app.include_router(worker.router)
    app.include_router(live.router)
    app.include_router(auth.router)
    app.include_router(studies.router)
    app.include_router(participants.router)
    app.include_router(sessions.router)
    app.include_router(questionnaires.router)
    app.include_router(preferences.router)
    app.include_router(participant_forms.router)
    app.include_router(participant_forms.pages)
    app.include_router(audit.router)
    app.include_router(recordings.router)
    app.include_router(model_sets.router)
    app.include_router(trials.router)
    app.include_router(trial_segments.router)
    app.include_router(results.router)
    app.include_router(console_pages.router)
    app.include_router(viewer.router)
    document_framework_errors(app)

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

    @app.get("/live", include_in_schema=False)
    def live_page(request: Request) -> Response:
        # Pages need a login like the API; without one, the login page brings you back.
        if login_from_token(app.state.sessions, request.cookies.get(SESSION_COOKIE)) is None:
            return RedirectResponse("/login?next=/live", status_code=303)
        return FileResponse(static / "live.html")

    @app.get("/login", include_in_schema=False)
    def login_page() -> FileResponse:
        return FileResponse(static / "login.html")

    return app
