"""The low-level controller (the paper's block diagram, bottom): encoder counts to
angles, the plausibility bounds of a sample, the lock hold (`e_k`), the actuator's
torque model and the hardware bring-up arithmetic. Everything between the device's
counts and the lock command; nothing here estimates intent or decides."""
