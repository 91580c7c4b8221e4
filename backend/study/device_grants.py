"""The lab's device grant: which accounts may use the exoskeleton.

Pulsing a solenoid, starting a controller or a trial and running the bring-up act on
the device a person wears. Creating a study costs nothing, so a study role cannot be
what allows that: an administrator gives each operator the grant (console `/admin`,
`PUT /api/device-grants/{username}`, `exostudy user grant-device NAME`) and takes it
back the same ways. Admins hold it implicitly. Every change is audited.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.core.errors import NotFoundError
from backend.db import audit
from backend.db.hardware import DeviceGrant
from backend.db.models import User

#: What a refusal says, and where the grant comes from.
MISSING = ("using the exoskeleton (solenoid pulses, controllers, trials, bring-up) needs "
           "the lab's device grant, which an administrator gives (console /admin, or "
           "`exostudy user grant-device NAME`); a study role does not include it")


def holds(db: Session, user: User) -> bool:
    """Whether `user` may use the device: an admin, or an active grant."""
    if user.role == "admin":
        return True
    return db.get(DeviceGrant, user.id) is not None


def holders(db: Session) -> list[tuple[User, DeviceGrant]]:
    """Every account with a grant, by name."""
    rows = db.execute(select(User, DeviceGrant)
                      .join(DeviceGrant, DeviceGrant.user_id == User.id)
                      .order_by(User.username))
    return [(u, g) for u, g in rows]


def parties(db: Session, g: DeviceGrant) -> tuple[User, str | None]:
    """The account holding `g` and the name of the one who gave it (None: given from
    the command line, or that account is gone)."""
    holder = db.get(User, g.user_id)
    assert holder is not None  # the grant's row goes with its account
    return holder, granter(db, g)


def granter(db: Session, g: DeviceGrant) -> str | None:
    """The name of the account that gave `g`, if any is left."""
    by = None if g.granted_by is None else db.get(User, g.granted_by)
    return None if by is None else by.username


def _account(db: Session, username: str) -> User:
    user = db.scalars(select(User).where(User.username == username)).first()
    if user is None:
        raise NotFoundError("account", username)
    return user


def grant(db: Session, by: User | str, username: str) -> DeviceGrant:
    """Give `username` the grant (kept as it is if it already holds one); audited."""
    user = _account(db, username)
    found = db.get(DeviceGrant, user.id)
    if found is not None:
        return found
    g = DeviceGrant(user_id=user.id, granted_by=by.id if isinstance(by, User) else None)
    db.add(g)
    audit.record(db, by, "grant_device", "user", user.id, {"username": user.username})
    db.commit()
    db.refresh(g)
    return g


def revoke(db: Session, by: User | str, username: str) -> bool:
    """Take the grant from `username`; False if it held none. Audited."""
    user = _account(db, username)
    found = db.get(DeviceGrant, user.id)
    if found is None:
        return False
    db.delete(found)
    audit.record(db, by, "revoke_device", "user", user.id, {"username": user.username})
    db.commit()
    return True
