"""Login, token and `me` bodies."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from backend.schemas.fields import UtcDatetime


class Credentials(BaseModel):
    """Username and password of an experimenter."""

    username: str = Field(min_length=1, max_length=64)
    password: str = Field(min_length=1, max_length=1024)


class UserOut(BaseModel):
    """An experimenter account (never the hash)."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    username: str
    active: bool
    created_at: UtcDatetime


class LoginOut(BaseModel):
    """A browser login: the session cookie is set; the token itself is not in the body."""

    user: UserOut
    expires_at: UtcDatetime


class TokenOut(BaseModel):
    """A bearer token for scripts: send `Authorization: Bearer <access_token>`."""

    access_token: str
    token_type: str = "bearer"
    expires_at: UtcDatetime
    user: UserOut
