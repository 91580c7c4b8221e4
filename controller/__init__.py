"""ExoStudy controllers: intent estimation and decision-theoretic locking for a
quasi-passive hip exoskeleton.

This package has no web or database code. It is used by the backend's worker process, by
offline replay and by the simulator; everything here runs without hardware.

The names below are the package's public API, imported on first use so that a light
user (the device simulator process) does not load the compiled controllers:

- choosing and building a controller: `ControllerConfig`, `ControllerSpec`,
  `SettingError`, `make_controller`, `make_from_spec`, `controller_names`;
- writing one (`docs/adding-a-controller.md`): `Controller`, `KernelController`,
  `Kernel`, `register`;
- running one: `ControlLoop`, `Sample`, `LockCommand`, `TickRecord`, and offline
  `AngleRecording`, `replay_columns`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from controller.config import ControllerConfig, SettingError
    from controller.controllers.factory import controller_names, make_controller, make_from_spec
    from controller.controllers.registry import register
    from controller.controllers.spec import ControllerSpec
    from controller.device.base import LockCommand, Sample
    from controller.interface import Controller
    from controller.kernel import Kernel, KernelController
    from controller.runner.loop import ControlLoop
    from controller.runner.replay import AngleRecording, replay_columns
    from controller.tick_record import TickRecord

_WHERE = {
    "Controller": "controller.interface",
    "ControllerConfig": "controller.config",
    "SettingError": "controller.config",
    "LockCommand": "controller.device.base",
    "Sample": "controller.device.base",
    "controller_names": "controller.controllers.factory",
    "make_controller": "controller.controllers.factory",
    "make_from_spec": "controller.controllers.factory",
    "Kernel": "controller.kernel",
    "KernelController": "controller.kernel",
    "ControlLoop": "controller.runner.loop",
    "register": "controller.controllers.registry",
    "AngleRecording": "controller.runner.replay",
    "replay_columns": "controller.runner.replay",
    "ControllerSpec": "controller.controllers.spec",
    "TickRecord": "controller.tick_record",
}

__all__ = [
    "AngleRecording", "ControlLoop", "Controller", "ControllerConfig", "ControllerSpec",
    "Kernel", "KernelController", "LockCommand", "Sample", "SettingError", "TickRecord",
    "controller_names", "make_controller", "make_from_spec", "register", "replay_columns",
]
assert sorted(__all__) == sorted(_WHERE)


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'controller' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
