"""Scheduling of the worker process and its loop thread.

A lock decision must not wait behind browsers, the web server or a CPU hog, so the
loop asks for a better place in the scheduler while a device paces it.
"""

from __future__ import annotations

import os
import resource
import signal
from types import FrameType

from backend.worker.messages import WorkerConfig


def raise_priority() -> None:
    """Ask the scheduler to prefer the control loop over browsers and the web server.
    Needs privileges (root or CAP_SYS_NICE); without them the loop runs at normal
    priority, which the benchmarks show is enough on an idle machine."""
    try:
        os.setpriority(os.PRIO_PROCESS, 0, -10)
    except (PermissionError, OSError):
        pass


#: Real-time priority of the loop thread (SCHED_FIFO, low in the 1..99 range: above
#: every ordinary process, below the kernel's own real-time threads).
LOOP_RT_PRIORITY = 10
#: A real-time thread that computes this long without sleeping is a runaway; the kernel
#: signals it (SIGXCPU) and the loop drops back to normal scheduling. A tick computes
#: in well under a millisecond and then sleeps until the next sample.
RT_RUNAWAY_US = 200_000


def paced(config: WorkerConfig) -> bool:
    """Whether the device's clock paces the loop (hardware, or real-time simulation)."""
    return config.device_kind != "sim" or config.device_speed <= 1.0


def loop_scheduling(device_paced: bool) -> None:
    """Real-time scheduling for the loop thread while it follows a device's clock.

    Nice -10 is a weight, not a guarantee: with both cores busy (benchmark
    `bench/bench_loop_load.py`) the woken loop still waits behind ordinary processes
    for milliseconds. SCHED_FIFO runs it as soon as its sample is due. Only for a
    device that paces the loop (hardware, or the simulator at real-time speed): a
    sped-up simulation runs flat out and must share the CPU with the server it feeds,
    so it gets normal scheduling. Needs root or CAP_SYS_NICE, else nothing changes.
    """
    try:
        if device_paced:
            signal.signal(signal.SIGXCPU, _drop_realtime)
            resource.setrlimit(resource.RLIMIT_RTTIME, (RT_RUNAWAY_US, RT_RUNAWAY_US * 10))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(LOOP_RT_PRIORITY))
        else:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (PermissionError, OSError, ValueError):
        pass


def _drop_realtime(_signum: int, _frame: FrameType | None) -> None:
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except OSError:
        pass
