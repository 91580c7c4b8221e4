"""Controllers by name, so that configuration (a database row, a CLI flag) can pick one.

A controller's configuration is a mapping:

    {"settings": {...ControllerConfig fields...},          # optional, defaults otherwise
     "models": {...ModelSet JSON...} or "models_path": "models.json",        # UMC, E-UMC
     "utilities": {...UtilitySet JSON...} or "utilities_path": "utilities.json"}
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from controller.base import Controller
from controller.config import ControllerConfig
from controller.motion_model import ModelSet
from controller.passthrough import PassThroughController
from controller.utilities import UtilitySet

Builder = Callable[[Mapping[str, Any]], Controller]


def _settings(cfg: Mapping[str, Any]) -> ControllerConfig:
    raw = cfg.get("settings", {})
    if isinstance(raw, ControllerConfig):
        return raw
    if not isinstance(raw, Mapping):
        raise ValueError("settings must be a mapping of controller parameters")
    return ControllerConfig.from_json(dict(raw))


def _load(cfg: Mapping[str, Any], key: str) -> dict[str, Any]:
    inline = cfg.get(key)
    if isinstance(inline, Mapping):
        return dict(inline)
    path = cfg.get(f"{key}_path")
    if path is None:
        raise ValueError(f"this controller needs '{key}' or '{key}_path' in its configuration")
    p = Path(str(path))
    if not p.is_file():
        raise ValueError(f"{key}_path: no such file {p}")
    try:
        data = json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{key}_path {p}: not valid JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise ValueError(f"{key}_path {p}: expected a JSON object")
    return data


def load_models(cfg: Mapping[str, Any]) -> ModelSet:
    """The model set named by a controller configuration."""
    return ModelSet.from_json(_load(cfg, "models"))


def load_utilities(cfg: Mapping[str, Any]) -> UtilitySet:
    """The utility set named by a controller configuration."""
    return UtilitySet.from_json(_load(cfg, "utilities"))


def _umc(cfg: Mapping[str, Any]) -> Controller:
    from controller.umc import UMC

    return UMC(load_models(cfg), load_utilities(cfg), _settings(cfg))


def _eumc(cfg: Mapping[str, Any]) -> Controller:
    from controller.umc import EUMC

    return EUMC(load_models(cfg), load_utilities(cfg), _settings(cfg))


def _pec(cfg: Mapping[str, Any]) -> Controller:
    from controller.pec import PEC

    return PEC(_settings(cfg))


def _none(cfg: Mapping[str, Any]) -> Controller:
    return PassThroughController(_settings(cfg).layout)


_REGISTRY: dict[str, Builder] = {"none": _none, "umc": _umc, "eumc": _eumc, "pec": _pec}

#: Controllers that need a model set and a utility set.
NEEDS_MODELS: frozenset[str] = frozenset({"umc", "eumc"})


def register(name: str, build: Builder) -> None:
    """Make a controller available under `name`."""
    _REGISTRY[name] = build


def controller_names() -> tuple[str, ...]:
    """Names accepted by `make_controller`."""
    return tuple(sorted(_REGISTRY))


def make_controller(name: str, config: Mapping[str, Any] | None = None) -> Controller:
    """Build the controller called `name` from its configuration."""
    try:
        build = _REGISTRY[name]
    except KeyError:
        raise ValueError(
            f"unknown controller {name!r}; choose one of {', '.join(controller_names())}"
        ) from None
    return build(config or {})
