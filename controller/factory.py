"""Controllers by name, so that configuration (a database row, a CLI flag) can pick one."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from controller.base import Controller
from controller.passthrough import PassThroughController

_REGISTRY: dict[str, Callable[[Mapping[str, Any]], Controller]] = {
    "none": lambda cfg: PassThroughController(),
}


def register(name: str, build: Callable[[Mapping[str, Any]], Controller]) -> None:
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
