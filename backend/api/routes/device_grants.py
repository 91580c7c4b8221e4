"""The lab's device grants over HTTP: an administrator gives or takes an account's right
to use the exoskeleton (`backend/study/device_grants.py`, docs/access.md)."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Response

from backend.api.deps import CurrentUser, SessionDep, access, current_user
from backend.api.errors import AUTH_RESPONSES, NOT_FOUND
from backend.core.errors import NotFoundError
from backend.db.hardware import DeviceGrant
from backend.db.models import User
from backend.schemas.hardware import DeviceGrantOut
from backend.study import device_grants

router = APIRouter(prefix="/api/device-grants", tags=["accounts"],
                   dependencies=[Depends(current_user)], responses=AUTH_RESPONSES)


def _out(user: User, g: DeviceGrant, by: str | None) -> DeviceGrantOut:
    return DeviceGrantOut(username=user.username, granted_at=g.granted_at, granted_by=by)


@router.get("", response_model=list[DeviceGrantOut], openapi_extra=access("admin"))
def list_device_grants(db: SessionDep) -> list[DeviceGrantOut]:
    """Every account holding the device grant (admins hold it without one)."""
    return [_out(u, g, device_grants.granter(db, g)) for u, g in device_grants.holders(db)]


@router.put("/{username}", response_model=DeviceGrantOut, responses=NOT_FOUND,
            openapi_extra=access("admin"))
def grant_device(username: str, user: CurrentUser, db: SessionDep) -> DeviceGrantOut:
    """Give the account the device grant (unchanged if it holds one)."""
    g = device_grants.grant(db, user, username)
    holder, by = device_grants.parties(db, g)
    return _out(holder, g, by)


@router.delete("/{username}", status_code=204, responses=NOT_FOUND,
               openapi_extra=access("admin"))
def revoke_device(username: str, user: CurrentUser, db: SessionDep) -> Response:
    """Take the device grant from the account (404 if it holds none)."""
    if not device_grants.revoke(db, user, username):
        raise NotFoundError("device grant of", username)
    return Response(status_code=204)
