"""The controller registry: every controller by name, and how to build it.

A controller module registers a builder (a `ControllerSpec` in, a `Controller` out)
under its name; configuration (a database row, a CLI flag, the worker pipe) then picks
it by that name through `controller.controllers.factory`. The controllers that ship with ExoStudy
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
    from controller.controllers.spec import ControllerSpec
    from controller.interface import Controller

Builder = Callable[["ControllerSpec"], "Controller"]

#: The modules of the controllers that ship with ExoStudy.
BUILTIN_MODULES = ("controller.controllers.passthrough", "controller.controllers.umc",
                   "controller.controllers.eumc", "controller.controllers.pec",
                   "controller.controllers.baselines")
#: Environment variable naming more controller modules to import (comma-separated).
ENV_MODULES = "EXOSTUDY_CONTROLLERS"
_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")
_COLOUR = re.compile(r"#[0-9a-fA-F]{6}")


@dataclass(frozen=True)
class PlanPlace:
    """Where a controller enters a study's counterbalanced trial plan (and a virtual
    cohort, which runs the planned controllers in `rank` order).

    The counterbalanced controllers come first, their order rotated from one
    participant to the next (`backend.study.counterbalance`); the others follow them in
    `rank` order. An `optional` one is planned only when the plan asks for the optional
    controllers."""

    rank: int
    counterbalanced: bool = True
    optional: bool = False
    #: A baseline condition (no exoskeleton, springs never locked): planned only when a
    #: plan asks for baselines, then counterbalanced and blinded like the controllers,
    #: and the reference that muscle-activity reductions are measured against.
    baseline: bool = False


@dataclass(frozen=True)
class Registration:
    """A registered controller: its name, its builder and what it declares about
    itself, so that the server, the worker, the replay and the results decide by
    capability rather than by name.

    Attributes:
        needs_models: needs a model set and a utility set (the specification then
            requires them).
        needs_calibration: runs only with calibration offsets (standing still before
            the trial); a trial refuses to start without one, the replay and the
            virtual cohort calibrate from the recording's start.
        estimates_intent: records posteriors, so its lifts are judged recognised and
            correct (a controller that does not gets neither judgement).
        label: how people read the name ("E-UMC"); the name itself if not given.
        colour: its colour in figures and pages (CSS hex); "": a spare one.
        marker: its matplotlib marker in figures; "": a spare one.
        plan: where it enters a counterbalanced trial plan; None: never planned.
        idle: the resting controller that never locks: the worker starts with it and
            returns to it (exactly one registration is idle).
        exoskeleton_worn: False for the "no exoskeleton" baseline: the wearer does not
            wear the device, so it gives no torque (the simulation removes it; in a lab
            its lifts come from the experimenter's markers, not the device's angles).
    """

    name: str
    build: Builder
    needs_models: bool = False
    needs_calibration: bool = False
    estimates_intent: bool = False
    label: str = ""
    colour: str = ""
    marker: str = ""
    plan: PlanPlace | None = None
    idle: bool = False
    exoskeleton_worn: bool = True

    @property
    def shown(self) -> str:
        """The label, or the name when no label was given."""
        return self.label or self.name


_REGISTRY: dict[str, Registration] = {}
_loaded = False


def register(name: str, *, needs_models: bool = False, needs_calibration: bool = False,
             estimates_intent: bool = False, label: str = "", colour: str = "",
             marker: str = "", plan: PlanPlace | None = None, idle: bool = False,
             exoskeleton_worn: bool = True) -> Callable[[Builder], Builder]:
    """Decorator: register the decorated builder as the controller `name`, with what it
    declares about itself (`Registration`).

    Names are short lowercase identifiers (they are stored with every trial); a name
    can be registered once.
    """
    if not _NAME.fullmatch(name):
        raise ValueError(f"controller name {name!r}: use 1-32 lowercase letters, digits "
                         "or '_', starting with a letter")
    if colour and not _COLOUR.fullmatch(colour):
        raise ValueError(f"controller {name!r}: colour {colour!r} is not a #rrggbb colour")

    def add(build: Builder) -> Builder:
        old = _REGISTRY.get(name)
        if old is not None and old.build is not build:
            raise ValueError(f"controller {name!r} is already registered")
        if idle and any(r.idle and r.name != name for r in _REGISTRY.values()):
            raise ValueError(f"controller {name!r}: another controller is already idle")
        _REGISTRY[name] = Registration(name, build, needs_models, needs_calibration,
                                       estimates_intent, label, colour, marker, plan, idle,
                                       exoskeleton_worn)
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


def get(name: str) -> Registration:
    """The registration of `name`; ValueError naming the known ones if unknown."""
    reg = lookup(name)
    if reg is None:
        raise ValueError(f"unknown controller {name!r}; choose one of {names()}")
    return reg


def needs_calibration(name: str) -> bool:
    """Whether the controller `name` runs only with calibration offsets."""
    reg = lookup(name)
    return reg is not None and reg.needs_calibration


def estimates_intent(name: str) -> bool | None:
    """Whether the controller `name` records posteriors; None if it is unknown (the
    evaluation then infers it from the recording)."""
    reg = lookup(name)
    return None if reg is None else reg.estimates_intent


def label(name: str) -> str:
    """How people read a controller's name; an unknown name is shown as given."""
    reg = lookup(name)
    return name if reg is None else reg.shown


def idle() -> str:
    """The name of the resting controller, which never locks."""
    _load()
    found = [r.name for r in _REGISTRY.values() if r.idle]
    if len(found) != 1:
        raise RuntimeError(f"exactly one controller must be registered idle, found {found}")
    return found[0]


def planned(include_baselines: bool = False) -> tuple[Registration, ...]:
    """The controllers that enter a trial plan, by their plan rank (then name); the
    baseline conditions only if asked for."""
    _load()
    regs = [r for r in _REGISTRY.values() if r.plan is not None
            and (include_baselines or not r.plan.baseline)]
    return tuple(sorted(regs, key=lambda r: (r.plan.rank if r.plan else 0, r.name)))


def display_order() -> tuple[str, ...]:
    """Every name in the order pages and tables list them: the planned controllers by
    rank, then the others by name, the idle one last."""
    plan = [r.name for r in planned(include_baselines=True)]
    rest = sorted(n for n in names() if n not in plan)
    return (*plan, *sorted(rest, key=lambda n: (_REGISTRY[n].idle, n)))


def baselines() -> tuple[str, ...]:
    """The baseline conditions' names, in plan rank order."""
    return tuple(r.name for r in planned(include_baselines=True)
                 if r.plan is not None and r.plan.baseline)


def exoskeleton_worn(name: str) -> bool:
    """Whether the wearer wears the exoskeleton under `name` (True for unknown names)."""
    reg = lookup(name)
    return reg is None or reg.exoskeleton_worn
