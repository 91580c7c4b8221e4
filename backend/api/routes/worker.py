"""Control of the worker process: restart after a failure, stop, choose a controller."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, HTTPException
from pydantic import BaseModel, Field

from backend.api.deps import RuntimeDep
from backend.schemas.live import Health
from controller.factory import controller_names

router = APIRouter(prefix="/api/worker", tags=["worker"])


class ControllerChoice(BaseModel):
    """Which controller the worker should run."""

    name: str = Field(description="controller name, e.g. none, umc, eumc, pec")
    config: dict[str, object] = Field(default_factory=dict)


@router.post("/restart", response_model=Health)
async def restart(runtime: RuntimeDep) -> Health:
    """Start the worker again (stopping it first if it still runs)."""
    await asyncio.to_thread(runtime.supervisor.restart)
    return runtime.health()


@router.post("/stop", response_model=Health)
async def stop(runtime: RuntimeDep) -> Health:
    """Release the device and stop the worker."""
    await asyncio.to_thread(runtime.supervisor.stop, "stopped by the experimenter")
    return runtime.health()


@router.get("/controllers", response_model=list[str])
def controllers() -> list[str]:
    """Controllers the worker can run."""
    return list(controller_names())


@router.post("/controller", response_model=Health)
def set_controller(choice: ControllerChoice, runtime: RuntimeDep) -> Health:
    """Switch controller; a new run starts in the database."""
    if choice.name not in controller_names():
        raise HTTPException(
            422, f"name: unknown controller {choice.name!r}; choose one of {controller_names()}"
        )
    runtime.supervisor.set_controller(choice.name, dict(choice.config))
    return runtime.health()
