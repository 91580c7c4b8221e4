"""Controllers by name, so that configuration (a database row, a CLI flag) can pick one.

Every build goes through `controller.spec.ControllerSpec`, which validates the name, the
settings and the set references first: a configuration that does not validate builds
nothing. The mapping form is described there.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from controller.base import Controller
from controller.motion_model import ModelSet
from controller.passthrough import PassThroughController
from controller.spec import CONTROLLER_NAMES, NEEDS_MODELS, ControllerSpec
from controller.utilities import UtilitySet

Builder = Callable[[ControllerSpec], Controller]

__all__ = ["NEEDS_MODELS", "ControllerSpec", "controller_names", "load_models",
           "load_utilities", "make_controller", "make_from_spec"]


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


def _umc(spec: ControllerSpec) -> Controller:
    from controller.umc import UMC

    return UMC(load_models(spec), load_utilities(spec), spec.settings)


def _eumc(spec: ControllerSpec) -> Controller:
    from controller.umc import EUMC

    return EUMC(load_models(spec), load_utilities(spec), spec.settings)


def _pec(spec: ControllerSpec) -> Controller:
    from controller.pec import PEC

    return PEC(spec.settings)


def _none(spec: ControllerSpec) -> Controller:
    return PassThroughController(spec.settings.layout)


_REGISTRY: dict[str, Builder] = {"none": _none, "umc": _umc, "eumc": _eumc, "pec": _pec}
assert set(_REGISTRY) == set(CONTROLLER_NAMES)


def controller_names() -> tuple[str, ...]:
    """Names accepted by `make_controller`."""
    return tuple(sorted(_REGISTRY))


def make_from_spec(spec: ControllerSpec) -> Controller:
    """Build the controller a validated specification names."""
    return _REGISTRY[spec.name](spec)


def make_controller(name: str, config: Mapping[str, Any] | None = None) -> Controller:
    """Build the controller called `name` from its configuration mapping, validating it
    first (`controller.config.SettingError`, a ValueError naming the field, if not)."""
    return make_from_spec(ControllerSpec.from_config(name, config))
