"""Dependencies shared by the routes (FastAPI `Annotated` aliases)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from backend.runtime import Runtime


def get_runtime(request: Request) -> Runtime:
    """The server's live path (created by the lifespan)."""
    runtime: Runtime = request.app.state.runtime
    return runtime


RuntimeDep = Annotated[Runtime, Depends(get_runtime)]
