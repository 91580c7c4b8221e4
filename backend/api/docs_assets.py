"""`/docs` from local files: Swagger UI from the `swagger-ui-dist` npm package (installed
by `make`), started by our own script, so the page works offline and under the app's
Content-Security-Policy (no inline script, no CDN)."""

from __future__ import annotations

import logging
from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

log = logging.getLogger(__name__)

_PAGE = """<!doctype html>
<html lang="en">
<head>
  <meta charset="utf-8">
  <title>ExoStudy API</title>
  <link rel="stylesheet" href="/docs-assets/swagger-ui.css">
</head>
<body>
  <div id="swagger-ui"></div>
  <script src="/docs-assets/swagger-ui-bundle.js"></script>
  <script src="/static/docs/init.js"></script>
</body>
</html>
"""


def install(app: FastAPI, frontend_dir: Path) -> None:
    """Mount the Swagger UI files and the `/docs` page."""
    dist = frontend_dir / "node_modules" / "swagger-ui-dist"
    if not dist.is_dir():
        log.warning("swagger-ui-dist not found at %s: run `make run` (npm ci); /docs is off",
                    dist)
        return
    app.mount("/docs-assets", StaticFiles(directory=dist), name="docs-assets")

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        return HTMLResponse(_PAGE)
