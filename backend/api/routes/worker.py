"""Control of the worker process: restart after a failure, stop, choose a controller."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, Depends, HTTPException

from backend.api.deps import RuntimeDep, SessionDep, access, current_user
from backend.api.errors import AUTH_RESPONSES, BODY, CONFLICT, MALFORMED, conflict, invalid
from backend.live.device_process import DeviceStartError
from backend.live.runtime import WorkerBusyError, WrongDeviceError
from backend.schemas.live import (
    CalibrationOutcome,
    CalibrationRequest,
    ControllerChoice,
    Health,
    SimulationChoice,
)
from backend.study import activity
from backend.study.conditions import spec_priors_problem
from controller.config import SettingError
from controller.controllers.factory import controller_names

# Every worker route needs a logged-in experimenter: they move a person's exoskeleton.
router = APIRouter(prefix="/api/worker", tags=["worker"],
                   dependencies=[Depends(current_user)], responses=AUTH_RESPONSES)


@router.post("/restart", response_model=Health, responses=CONFLICT,
             openapi_extra=access("worker"))
async def restart(runtime: RuntimeDep) -> Health:
    """Start the worker again (stopping it first if it still runs)."""
    try:
        await asyncio.to_thread(runtime.supervisor.restart)
    except WorkerBusyError as exc:
        conflict("worker", str(exc))
    return runtime.health()


@router.post("/stop", response_model=Health, openapi_extra=access("worker"))
async def stop(runtime: RuntimeDep) -> Health:
    """Release the device and stop the worker."""
    await asyncio.to_thread(runtime.supervisor.stop, "stopped by the experimenter")
    return runtime.health()


@router.get("/controllers", response_model=list[str])
def controllers() -> list[str]:
    """Controllers the worker can run."""
    return list(controller_names())


def _ensure_no_activity(db: SessionDep, what: str) -> None:
    """409 while a trial or recording runs: `what` would replace its run silently."""
    busy = activity.running(db)
    if busy is not None:
        conflict("worker", f"{busy} is running: stop it before {what}")


@router.post("/controller", response_model=Health, responses={**BODY, **CONFLICT},
             openapi_extra=access("device"))
async def set_controller(choice: ControllerChoice, runtime: RuntimeDep,
                         db: SessionDep) -> Health:
    """Switch controller; a new run starts in the database. `config` overrides controller
    settings (rates, thresholds, priors: see `controller.config.ControllerConfig`).
    409 while a trial or recording runs: its controller is the one it was started with."""
    async with runtime.activity:
        _ensure_no_activity(db, "changing the controller")
        return _set_controller(choice, runtime)


def _set_controller(choice: ControllerChoice, runtime: RuntimeDep) -> Health:
    if choice.name not in controller_names():
        raise HTTPException(
            422, f"name: unknown controller {choice.name!r}; choose one of {controller_names()}"
        )
    try:
        # Priors from the body are checked against the utility set here (422), not
        # only by the controller in the worker (which refuses them again).
        problem = spec_priors_problem(runtime.controller_spec(choice.name,
                                                              dict(choice.config)))
        if problem is not None:
            invalid(["body", "config", "priors"], problem)
        runtime.set_controller(choice.name, dict(choice.config))
    except WrongDeviceError as exc:
        conflict("device", str(exc))
    except SettingError as exc:
        invalid(["body", "config", exc.field], exc.problem)
    except (ValueError, TypeError) as exc:
        raise HTTPException(422, f"config: {exc}") from exc
    return runtime.health()


@router.post("/calibrate", response_model=CalibrationOutcome, openapi_extra=access("worker"),
             responses={**MALFORMED, 409: {"description": "no worker running"},
                        422: {"description": "the wearer moved, or too few samples"}})
async def calibrate(req: CalibrationRequest, runtime: RuntimeDep,
                    db: SessionDep) -> CalibrationOutcome:
    """E-UMC calibration: record the next seconds of standing still and compute the
    offsets that map the rest posture onto the models' start. A running E-UMC takes
    them at once; an E-UMC chosen later gets them too. 409 during a trial (a running
    E-UMC taking new offsets would change the trial's controller)."""
    import math

    async with runtime.activity:
        busy = activity.running(db)
        if busy is not None and busy.startswith("trial"):
            conflict("worker", f"{busy} is running: calibrate before starting it")
        try:
            r = await runtime.calibrate(req.seconds, req.max_std_deg)
        except RuntimeError as exc:
            raise HTTPException(409, str(exc)) from exc
        except TimeoutError as exc:
            raise HTTPException(409, "the worker did not answer the calibration "
                                "request") from exc
    out = CalibrationOutcome(
        ok=r.ok, message=r.message,
        offset_left_deg=math.degrees(r.offset_left), offset_right_deg=math.degrees(r.offset_right),
        std_left_deg=None if math.isnan(r.std_left_deg) else r.std_left_deg,
        std_right_deg=None if math.isnan(r.std_right_deg) else r.std_right_deg,
        samples=r.samples,
    )
    if not r.ok:
        raise HTTPException(422, out.model_dump())
    return out


@router.post("/simulation", response_model=Health, openapi_extra=access("worker"),
             responses={**MALFORMED, **CONFLICT,
                        422: {"description": "unknown script, a speed for a device that is not "
                                         "the in-process simulator, or hardware"},
                        503: {"description": "the simulated device process could not start "
                                         "(the reason is given)"}})
async def set_simulation(choice: SimulationChoice, runtime: RuntimeDep,
                         db: SessionDep) -> Health:
    """Change the simulated wearer (seed) or script; a new run starts on the new one.
    409 while a trial or recording runs; 503 if the device process cannot start."""
    async with runtime.activity:
        _ensure_no_activity(db, "changing the simulation")
        return await _set_simulation(choice, runtime)


async def _set_simulation(choice: SimulationChoice, runtime: RuntimeDep) -> Health:
    try:
        await runtime.set_simulation(choice.seed, choice.script, choice.speed)
    except DeviceStartError as exc:
        raise HTTPException(503, f"device: {exc}") from exc
    except ValueError as exc:
        raise HTTPException(422, str(exc)) from exc
    except RuntimeError as exc:
        raise HTTPException(409, str(exc)) from exc
    return runtime.health()
