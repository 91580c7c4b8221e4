"""Controller specifications that skip validation: what a bug in the server, or anything
else writing to the worker's pipe, could send. The worker must validate them again."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from controller.config import ControllerConfig
from controller.controllers.spec import ControllerSpec


def unchecked_spec(name: str, config: Mapping[str, Any] | None = None) -> ControllerSpec:
    """A `ControllerSpec` of `name` with the wire mapping `config` (settings, set
    references), built without running its checks or those of its settings; it pickles
    as it is (unpickling runs no checks either)."""
    cfg = dict(config or {})
    settings = ControllerConfig()
    for key, value in dict(cfg.get("settings", {})).items():
        object.__setattr__(settings, key, value)
    spec = object.__new__(ControllerSpec)
    fields = {"name": name, "settings": settings, "models": cfg.get("models"),
              "models_path": cfg.get("models_path"), "utilities": cfg.get("utilities"),
              "utilities_path": cfg.get("utilities_path")}
    for key, value in fields.items():
        object.__setattr__(spec, key, value)
    return spec
