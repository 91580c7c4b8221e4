"""Study bodies."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from backend.schemas.fields import Name, PlainText, UtcDatetime, _storable

#: A site's short name ("Leuven", "site-2").
SiteName = Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9 ._-]{0,63}$")]


ShortText = Annotated[str, Field(max_length=500), AfterValidator(_storable)]


class DatasetInfo(BaseModel):
    """What a shared dataset says about itself (BIDS' `dataset_description.json` and
    the motion sidecars): who made it, under which licence, at which institution, and
    what participants were told. Empty fields are left out of the export."""

    model_config = ConfigDict(extra="forbid")

    authors: list[Annotated[str, Field(min_length=1, max_length=200),
                            AfterValidator(_storable)]] = Field(
        default_factory=list, max_length=100, description="one person per entry")
    license: ShortText = Field(default="", description="licence of the shared data, as a "
                               "SPDX identifier where one exists (e.g. CC0-1.0, CC-BY-4.0)")
    institution_name: ShortText = ""
    institution_address: ShortText = ""
    institution_department: ShortText = ""
    instructions: PlainText = Field(default="", description="what participants were told "
                                    "before each trial")
    funding: list[Annotated[str, Field(min_length=1, max_length=500),
                            AfterValidator(_storable)]] = Field(default_factory=list,
                                                                max_length=50)


class StudyIn(BaseModel):
    """A new study; the name is unique."""

    model_config = ConfigDict(extra="forbid")

    name: Name
    description: PlainText = ""
    #: What withdrawal does: erase the participant's data, or keep it excluded.
    withdrawal_policy: Literal["erase", "exclude"] = "erase"
    dataset_info: DatasetInfo = Field(default_factory=DatasetInfo)


class StudyUpdate(BaseModel):
    """Fields to change; absent fields stay as they are."""

    model_config = ConfigDict(extra="forbid")

    name: Name | None = None
    description: PlainText | None = None
    withdrawal_policy: Literal["erase", "exclude"] | None = None
    dataset_info: DatasetInfo | None = None


class StudyOut(BaseModel):
    """A study."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    description: str
    created_by: int | None
    created_at: UtcDatetime
    withdrawal_policy: str
    dataset_info: DatasetInfo


class MemberIn(BaseModel):
    """An account's role in a study, optionally limited to one site's participants."""

    model_config = ConfigDict(extra="forbid")

    username: Annotated[str, Field(min_length=1, max_length=64,
                                   pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]*$")]
    role: Literal["owner", "experimenter", "viewer"]
    site: SiteName | None = None


class MemberOut(BaseModel):
    """A study member."""

    user_id: int
    username: str
    role: str
    site: str | None


class ConsentIn(BaseModel):
    """A new version of the study's consent document."""

    model_config = ConfigDict(extra="forbid")

    version: Annotated[str, Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]{0,31}$")]
    text: Annotated[str, Field(min_length=1, max_length=100_000), AfterValidator(_storable)]


class ConsentOut(BaseModel):
    """A consent document version."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    version: str
    text: str
    created_at: UtcDatetime
