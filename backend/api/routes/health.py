"""Health of the live path: worker, device, database writer."""

from __future__ import annotations

from fastapi import APIRouter

from backend.api.deps import RuntimeDep, access
from backend.schemas.live import Health

router = APIRouter(tags=["health"])


@router.get("/api/health", response_model=Health, openapi_extra=access("public"))
def health(runtime: RuntimeDep) -> Health:
    """Is the worker alive, is the device sending, are ticks being stored?"""
    return runtime.health()
