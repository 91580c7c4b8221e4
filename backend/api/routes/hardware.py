"""Hardware bring-up: encoder zero, directions, cam offset, solenoid pulse, watchdog and
link checks, and the hardware profile they produce (docs/hardware-bringup.md).

Every step moves or energises the exoskeleton, so it needs the lab's device grant
(rule `device`, given by an administrator) and is refused (409) while a trial or
recording runs or a controller other than `none` is active, and so is storing the
profile; a pulse, watchdog or hardware release test also needs `nobody_wearing` (JSON
true) and a solenoid that is not cooling down (409 with the time to wait).
"""

from __future__ import annotations

from fastapi import APIRouter, Depends

from backend.api.deps import CurrentUser, RuntimeDep, SessionDep, access, current_user
from backend.api.errors import AUTH_RESPONSES, BODY, CONFLICT, NOT_FOUND
from backend.api.params import HardwareProfileId
from backend.db.hardware import HardwareProfile
from backend.schemas.hardware import (
    CaptureIn,
    DirectionIn,
    FinishIn,
    HardwareStateOut,
    ProfileOut,
    PulseIn,
    ReleaseIn,
    StepResultOut,
    WatchdogIn,
)
from backend.study import hardware_profiles as hw

router = APIRouter(prefix="/api/hardware", tags=["hardware"],
                   dependencies=[Depends(current_user)], responses=AUTH_RESPONSES)
_STEP_RESPONSES = {**BODY, **CONFLICT}


@router.get("", response_model=HardwareStateOut, openapi_extra=access("experimenter"))
def hardware_state(db: SessionDep, runtime: RuntimeDep) -> HardwareStateOut:
    """The bring-up in progress, the profile in effect and the layout applied now."""
    return hw.state(db, runtime)


@router.get("/profiles", response_model=list[ProfileOut], openapi_extra=access("experimenter"))
def profiles(db: SessionDep) -> list[HardwareProfile]:
    """Every hardware profile, newest first."""
    return hw.list_profiles(db)


@router.get("/profiles/{profile_id}", response_model=ProfileOut, responses=NOT_FOUND,
            openapi_extra=access("experimenter"))
def profile(profile_id: HardwareProfileId, db: SessionDep) -> HardwareProfile:
    """One hardware profile."""
    return hw.get(db, profile_id)


@router.post("/zero", response_model=StepResultOut, responses=_STEP_RESPONSES,
             openapi_extra=access("device"))
async def zero(body: CaptureIn, user: CurrentUser, db: SessionDep,
               runtime: RuntimeDep) -> StepResultOut:
    """Step a: average `seconds` of still standing; each encoder's count becomes its zero."""
    return await hw.zero(db, user, runtime, body)


@router.post("/direction", response_model=StepResultOut, responses=_STEP_RESPONSES,
             openapi_extra=access("device"))
async def direction(body: DirectionIn, user: CurrentUser, db: SessionDep,
                    runtime: RuntimeDep) -> StepResultOut:
    """Step b: flex the `side` hip during the capture; stores its encoders' signs."""
    return await hw.direction(db, user, runtime, body)


@router.post("/offset", response_model=StepResultOut, responses=_STEP_RESPONSES,
             openapi_extra=access("device"))
async def offset(body: CaptureIn, user: CurrentUser, db: SessionDep,
                 runtime: RuntimeDep) -> StepResultOut:
    """Step c: the cam encoders' zeros so that alpha is 0 while unlocked."""
    return await hw.offset(db, user, runtime, body)


@router.post("/pulse", response_model=StepResultOut, responses=_STEP_RESPONSES,
             openapi_extra=access("device"))
async def pulse(body: PulseIn, user: CurrentUser, db: SessionDep,
                runtime: RuntimeDep) -> StepResultOut:
    """Step d: one solenoid pulse (at most 300 ms) on an unloaded device nobody wears."""
    return await hw.pulse(db, user, runtime, body)


@router.post("/watchdog", response_model=StepResultOut, responses=_STEP_RESPONSES,
             openapi_extra=access("device"))
async def watchdog(body: WatchdogIn, user: CurrentUser, db: SessionDep,
                   runtime: RuntimeDep) -> StepResultOut:
    """Step e: energise one side, stop commanding, time the device's watchdog release."""
    return await hw.watchdog(db, user, runtime, body)


@router.post("/release", response_model=StepResultOut, responses=_STEP_RESPONSES,
             openapi_extra=access("device"))
async def hardware_release(body: ReleaseIn, user: CurrentUser, db: SessionDep,
                           runtime: RuntimeDep) -> StepResultOut:
    """Step f: energise one side, stop the firmware's heartbeat output, time the hardware
    monitor's release of the drivers (device clock; at most 30 ms + 2 sample periods)."""
    return await hw.hardware_release(db, user, runtime, body)


@router.post("/link", response_model=StepResultOut, responses=_STEP_RESPONSES,
             openapi_extra=access("device"))
async def link(user: CurrentUser, db: SessionDep, runtime: RuntimeDep) -> StepResultOut:
    """Step g: the link's statistics (drops by reason, gaps, timing)."""
    return await hw.link(db, user, runtime)


@router.post("/profile", response_model=ProfileOut, responses={**BODY, **CONFLICT},
             openapi_extra=access("device"))
async def finish(body: FinishIn, user: CurrentUser, db: SessionDep,
                 runtime: RuntimeDep) -> HardwareProfile:
    """Close the bring-up: `complete` (in effect from now on, on the device it was made
    on) if every step passed, else `failed`. 409 while something runs, and when the
    draft expired or belongs to another device."""
    return await hw.finish(db, user, runtime, body)
