"""ExoStudy server: study management, the supervised control worker, storage and streaming."""
