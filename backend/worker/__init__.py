"""The control worker: a separate process running the 100 Hz loop, and its supervisor."""
