"""The controller registry: every controller by name, and how to build it.

A controller module registers a builder (a `ControllerSpec` in, a `Controller` out)
under its name; configuration (a database row, a CLI flag, the worker pipe) then picks
it by that name through `controller.factory`. The controllers that ship with ExoStudy
register when their modules are imported, which happens the first time a name is looked
up; more modules can be named in the environment variable `EXOSTUDY_CONTROLLERS`
(comma-separated module paths), so that a worker process, which imports nothing of its
parent's, knows a controller a researcher added outside this package.
"""

from __future__ import annotations

import importlib
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from controller.base import Controller
    from controller.spec import ControllerSpec

Builder = Callable[["ControllerSpec"], "Controller"]

#: The modules of the controllers that ship with ExoStudy.
BUILTIN_MODULES = ("controller.passthrough", "controller.umc", "controller.eumc",
                   "controller.pec")
#: Environment variable naming more controller modules to import (comma-separated).
ENV_MODULES = "EXOSTUDY_CONTROLLERS"
_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")


@dataclass(frozen=True)
class Registration:
    """A registered controller: its name, builder and whether it needs model and
    utility sets (the specification then requires them)."""

    name: str
    build: Builder
    needs_models: bool


_REGISTRY: dict[str, Registration] = {}
_loaded = False


def register(name: str, *, needs_models: bool = False) -> Callable[[Builder], Builder]:
    """Decorator: register the decorated builder as the controller `name`.

    Names are short lowercase identifiers (they are stored with every trial); a name
    can be registered once.
    """
    if not _NAME.fullmatch(name):
        raise ValueError(f"controller name {name!r}: use 1-32 lowercase letters, digits "
                         "or '_', starting with a letter")

    def add(build: Builder) -> Builder:
        old = _REGISTRY.get(name)
        if old is not None and old.build is not build:
            raise ValueError(f"controller {name!r} is already registered")
        _REGISTRY[name] = Registration(name, build, needs_models)
        return build

    return add


def unregister(name: str) -> None:
    """Remove a registration (for tests that register a controller of their own)."""
    _REGISTRY.pop(name, None)


def _load() -> None:
    """Import the controller modules once, so that they register."""
    global _loaded
    if _loaded:
        return
    for module in BUILTIN_MODULES:
        importlib.import_module(module)
    for module in (m.strip() for m in os.environ.get(ENV_MODULES, "").split(",")):
        if not module:
            continue
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise RuntimeError(f"{ENV_MODULES}: cannot import controller module "
                               f"{module!r}: {exc}") from exc
    _loaded = True


def names() -> tuple[str, ...]:
    """Every registered controller name, sorted."""
    _load()
    return tuple(sorted(_REGISTRY))


def lookup(name: str) -> Registration | None:
    """The registration of `name`, or None."""
    _load()
    return _REGISTRY.get(name)
