"""Login, token and `me` bodies."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from backend.schemas.fields import UtcDatetime, _storable

#: A password as typed: any characters the database and argon2 can take.
Secret = Annotated[str, Field(min_length=1, max_length=1024), AfterValidator(_storable)]


class Credentials(BaseModel):
    """Username and password of an experimenter."""

    username: Annotated[str, Field(min_length=1, max_length=64), AfterValidator(_storable)]
    password: Secret


class UserOut(BaseModel):
    """An experimenter account (never the hash)."""

    model_config = ConfigDict(from_attributes=True, populate_by_name=True)

    id: int
    username: str
    active: bool
    created_at: UtcDatetime
    role: str
    #: True while the account's secret is the published demo one (pages warn).
    published_login: bool = Field(validation_alias="password_published")


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


class Me(UserOut):
    """Who is logged in, and what every page should warn about."""

    #: Accounts whose password is still the published demo one (every page warns).
    published_login_accounts: list[str]


class PasswordChange(BaseModel):
    """The current password (proves it is the owner at the keyboard) and the new one."""

    current_password: Secret
    new_password: Secret


class NewAccount(BaseModel):
    """An account an admin creates."""

    username: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
    password: Secret
    role: Literal["admin", "member"] = "member"


class AccountUpdate(BaseModel):
    """What an admin changes on an account: role, enabled, or a new password."""

    role: Literal["admin", "member"] | None = None
    active: bool | None = None
    password: Secret | None = None
