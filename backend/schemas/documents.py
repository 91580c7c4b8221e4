"""The versioned JSON documents the API hands out as they are stored: a fitted model set
and a computed utility set (the files `exostudy replay` and the worker read), and a
trial's ticks as columns.

The documents are written by `controller.intent.motion_model.ModelSet.to_json` and
`controller.decision.utility_function.UtilitySet.to_json`, which own their format; these
models name the top-level keys for the OpenAPI schema and let any other key through
unchanged (routes answer with `response_model_exclude_unset`, so a key a document lacks
stays absent).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field


class _Document(BaseModel):
    model_config = ConfigDict(extra="allow")

    format: str | None = Field(default=None, description="the document's format name")
    format_version: int | None = None
    created: str | None = Field(default=None, description="ISO 8601 time of creation")
    n_progress: int | None = Field(default=None, description="progress bins")
    meta: dict[str, Any] | None = None


class ModelSetDocument(_Document):
    """A fitted model set: one probabilistic motion model per motion."""

    version: str | None = Field(default=None, description="the set's own version string")
    stacking: str | None = Field(default=None, description="how both legs' angles are "
                                 "stacked in a sample")
    fit_params: dict[str, Any] | None = None
    demonstrations: dict[str, Any] | None = Field(default=None, description="which "
                                                  "demonstrations each model was fitted on")
    models: dict[str, dict[str, Any]] | None = Field(default=None, description=(
        "motion -> mean_rad, cov_rad2, online_n, q, sigma2, explained_variance, "
        "n_demonstrations, w"))


class UtilitySetDocument(_Document):
    """A computed utility set: the utility of each action for each motion and progress."""

    precompression_pct: float | None = None
    actuator: dict[str, Any] | None = None
    human_data: dict[str, Any] | None = Field(default=None, description="source and "
                                              "version of the human motion data")
    actions: list[str] | None = None
    categories: list[str] | None = None
    utilities_nm2: list[Any] | None = Field(default=None, description="utilities (N²m²) "
                                            "indexed [action][category][progress]")


class TickColumnsOut(BaseModel):
    """A trial's ticks as columns: field -> one value per tick (null where not computed).
    Which fields and their units: the study export's data dictionary."""

    trial_id: int
    columns: dict[str, list[float | int | str | bool | None]]
