"""ExoStudy controllers: intent estimation and decision-theoretic locking for a
quasi-passive hip exoskeleton.

This package has no web or database code. It is used by the backend's worker process, by
offline replay and by the simulator; everything here runs without hardware.
"""
