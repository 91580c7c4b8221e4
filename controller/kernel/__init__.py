"""The compiled control tick shared by every controller, live and in replay.

- `records`: the typed state records (`SETTINGS`, `REFERENCE`, `PHASE`), the named
  output row (`ROW`, fields `ROW_FIELDS`) and `TickState`, which groups them.
- `check`: the plausibility check of a decoded sample.
- `tick`: the tick itself, `begin` and `finish` around a controller's decision step,
  and `replay_sample`, the mechanism's sample in a batch replay.
- `core`: `Kernel`, one controller's state and compiled tick, and `Compiled`, the two
  entry points a controller module compiles with its decision step.
- `entry_points`: `entry_points(decide)`, a controller's `Compiled` pair built from
  its decision step.
- `controller`: `KernelController`, the `Controller` a decision module subclasses.

The package re-exports nothing: import from the module. How a tick flows and how to
add a controller: `docs/controller-kernel.md` and `docs/adding-a-controller.md`.
"""
