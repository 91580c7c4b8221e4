"""The live session: the runtime that owns the worker and the device process, the tick
recorder, the browser stream, the 3D viewer, and the local server the app runs as."""
