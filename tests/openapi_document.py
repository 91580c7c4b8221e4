"""The app's OpenAPI document as the default settings build it, once per test process.

Modules that parametrize their tests by the documented operations read it while pytest
collects; each built an app and its document of its own (about 1 s of CPU each, in
every test process), for the same document. Read-only: callers must not change it."""

from __future__ import annotations

import functools
from typing import Any


@functools.cache
def documented() -> dict[str, Any]:
    """The OpenAPI document of an app on the embedded defaults (building the app has no
    side effects; only its lifespan would touch anything)."""
    from backend.core.config import Settings
    from backend.main import create_app

    app = create_app(Settings(_env_file=None, start_worker=False))  # type: ignore[call-arg]
    return app.openapi()
