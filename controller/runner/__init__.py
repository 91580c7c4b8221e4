"""Running a controller: the soft real-time control loop (live) and the offline replay
of recorded hip angles through the same tick code (`python -m controller.runner.replay`)."""
