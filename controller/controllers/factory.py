"""Controllers by name, so that configuration (a database row, a CLI flag) can pick one.

Each controller registers its builder in `controller.controllers.registry`; this module loads the
sets a specification references and builds through the registry.

Every build goes through `controller.controllers.spec.ControllerSpec`, which validates the name, the
settings and the set references first: a configuration that does not validate builds
nothing. The mapping form is described there.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from controller.controllers import registry
from controller.controllers.spec import ControllerSpec
from controller.decision.utility_function import UtilitySet
from controller.intent.motion_model import ModelSet
from controller.interface import Controller

__all__ = ["ControllerSpec", "controller_names", "load_models",
           "load_utilities", "make_controller", "make_from_spec", "needs_models"]


def _load(spec: ControllerSpec | Mapping[str, Any], key: str) -> dict[str, Any]:
    if isinstance(spec, ControllerSpec):
        inline, path = getattr(spec, key), getattr(spec, f"{key}_path")
    else:
        inline, path = spec.get(key), spec.get(f"{key}_path")
    if isinstance(inline, Mapping):
        return dict(inline)
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


def load_models(cfg: ControllerSpec | Mapping[str, Any]) -> ModelSet:
    """The model set named by a controller configuration."""
    return ModelSet.from_json(_load(cfg, "models"))


def load_utilities(cfg: ControllerSpec | Mapping[str, Any]) -> UtilitySet:
    """The utility set named by a controller configuration."""
    return UtilitySet.from_json(_load(cfg, "utilities"))


def controller_names() -> tuple[str, ...]:
    """Names accepted by `make_controller`: every registered controller."""
    return registry.names()


def needs_models(name: str) -> bool:
    """Whether the controller `name` needs a model and a utility set."""
    reg = registry.lookup(name)
    return reg is not None and reg.needs_models


def make_from_spec(spec: ControllerSpec) -> Controller:
    """Build the controller a validated specification names, with its registered
    builder (`controller.controllers.registry`): the one place a controller is built."""
    reg = registry.lookup(spec.name)
    assert reg is not None  # the specification validated the name
    return reg.build(spec)


def make_controller(name: str, config: Mapping[str, Any] | None = None) -> Controller:
    """Build the controller called `name` from its configuration mapping, validating it
    first (`controller.config.SettingError`, a ValueError naming the field, if not)."""
    return make_from_spec(ControllerSpec.from_config(name, config))
