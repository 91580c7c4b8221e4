"""ExoStudy controllers: intent estimation and decision-theoretic locking for a
quasi-passive hip exoskeleton.

This package has no web or database code. It is used by the backend's worker process, by
offline replay and by the simulator; everything here runs without hardware.

A bare package: it holds no code (tests/test_import_directions.py), so importing one part
(the device simulator process imports `controller.sim`) loads nothing else. Import each
name from the module that defines it:

- choosing and building a controller: `controller.config` (`ControllerConfig`,
  `SettingError`), `controller.controllers.spec` (`ControllerSpec`),
  `controller.controllers.factory` (`make_controller`, `make_from_spec`,
  `controller_names`);
- writing one (`docs/adding-a-controller.md`): `controller.interface` (`Controller`),
  `controller.kernel` (`Kernel`, `KernelController`), `controller.controllers.registry`
  (`register`);
- running one: `controller.runner.loop` (`ControlLoop`), `controller.device.base`
  (`Sample`, `LockCommand`), `controller.tick_record` (`TickRecord`), and offline
  `controller.runner.replay` (`AngleRecording`, `replay_columns`).
"""
